"""Rebuilds src/solve/materials.json, the built-in material library, from its sources.

    python bench/materials.py PYLEECAN_SRC > src/solve/materials.json

PYLEECAN_SRC is the unpacked sdist of pyleecan 1.4.2 (Apache-2.0):
`pip download --no-deps --no-binary :all: pyleecan==1.4.2` and untar it. Steels and NdFeB
grades come from its pyleecan/Data/Material/*.json; the ferrite grade and aluminium's
conductivity are single published figures of FEMM 4.2's matlib.dat, written below with the
entry they come from. Nothing else is typed in.
"""
import json
import math
import sys
from pathlib import Path

MU_0 = 4e-7 * math.pi  # pyleecan's own μ0, which its Hc = Br / (μ0 μr) used
PYLEECAN = "pyleecan 1.4.2, pyleecan/Data/Material/{}"


def pyleecan(root, file):
    return json.loads((Path(root) / "pyleecan/Data/Material" / file).read_text())


def steel(root, name, file, note=""):
    data = pyleecan(root, file)
    table = data["mag"]["BH_curve"]["value"]
    assert table[0] == [0.0, 0.0]
    for (h0, b0), (h1, b1) in zip(table, table[1:]):
        assert h1 > h0 and b1 > b0, (name, h0, h1, b0, b1)
    return {"name": name, "kind": "steel", "bh": table, "source": PYLEECAN.format(file) + note}


def magnet(root, name, file):
    mag = pyleecan(root, file)["mag"]
    return {
        "name": name,
        "kind": "magnet",
        "mu_r": float(mag["mur_lin"]),
        "br": float(mag["Brm20"]),
        "source": PYLEECAN.format(file) + " (Brm20 at 20 °C, mur_lin)",
    }


def conductor(root, name, file):
    data = pyleecan(root, file)
    return {
        "name": name,
        "kind": "conductor",
        "mu_r": 1.0,
        "conductivity": 1.0 / float(data["elec"]["rho"]),
        "source": PYLEECAN.format(file) + " (1 / rho)",
    }


def main(root):
    library = [
        {"name": "air", "kind": "air", "mu_r": 1.0, "source": "μr = 1"},
        conductor(root, "copper", "Copper1.json"),
        {
            "name": "aluminium",
            "kind": "conductor",
            "mu_r": 1.0,
            "conductivity": 34.45e6,
            "source": 'FEMM 4.2 matlib.dat, "Aluminum, 1100" (Sigma 34.45 MS/m)',
        },
        steel(root, "M235-35A", "M235-35A.json"),
        steel(root, "M270-35A", "M270-35A.json", " (the table ends at 1.8 T)"),
        steel(root, "M400-50A", "M400-50A.json"),
        steel(root, "M530-65A", "M530-65A.json"),
        steel(root, "M-19", "M19.json", " (the table of FEMM's \"M-19 Steel\")"),
        magnet(root, "N45", "Magnet_N45.json"),
        magnet(root, "N48", "Magnet_N48.json"),
        magnet(root, "N50", "Magnet_N50.json"),
        magnet(root, "N52", "Magnet_N52.json"),
        {
            "name": "ceramic-8",
            "kind": "magnet",
            "br": 0.39145,
            "hc": 233568.0,
            "source": 'FEMM 4.2 matlib.dat, "Ceramic 8": Hc, and Br as its demagnetisation curve\'s B at Hc; '
            "taken as a straight recoil line through both",
        },
    ]
    json.dump(library, sys.stdout, indent=1, ensure_ascii=False)
    print()


if __name__ == "__main__":
    main(sys.argv[1])
