#!/usr/bin/env python3
"""Writes the seed inputs of the `grid_file` fuzz target into fuzz/seeds/grid_file/.

Each seed is a 3-byte hint prefix (flags, nx, ny; see fuzz_targets/grid_file.rs) followed by
one small valid grid file: .npy (several dtypes, byte orders, Fortran order, version 2),
PNG (8- and 16-bit grey, grey with alpha, tRNS), TIFF (little- and big-endian, deflate,
BigTIFF), GeoTIFF (pixel scale and tie point, transformation matrix, GDAL_NODATA), raw
f32/f64 and JSON. Standard library only: `python3 fuzz/seeds/make_grid_seeds.py`.
"""

import json
import os
import struct
import zlib

OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "grid_file")

NO_HINTS = bytes([0, 0, 0])


def hints(nx=None, ny=None, dtype=None):
    flags = (nx is not None) | (ny is not None) << 1 | {None: 0, "f32": 1, "f64": 2}[dtype] << 2
    return bytes([flags, nx or 0, ny or 0])


# ---- .npy ----------------------------------------------------------------------------------


def npy(descr, shape, values, fortran=False, version=1):
    header = "{'descr': '%s', 'fortran_order': %s, 'shape': (%s), }" % (
        descr,
        "True" if fortran else "False",
        ", ".join(str(n) for n in shape) + ("," if len(shape) == 1 else ""),
    )
    lead = 10 if version == 1 else 12
    pad = (64 - (lead + len(header) + 1) % 64) % 64
    header = (header + " " * pad + "\n").encode()
    length = struct.pack("<H", len(header)) if version == 1 else struct.pack("<I", len(header))
    order = "<" if descr[0] == "|" else descr[0]
    code = {"f4": "f", "f8": "d", "i1": "b", "u1": "B", "i2": "h", "u2": "H", "i4": "i", "u4": "I"}[descr[1:]]
    data = struct.pack(order + code * len(values), *values)
    return b"\x93NUMPY" + bytes([version, 0]) + length + header + data


# ---- PNG -----------------------------------------------------------------------------------


def chunk(kind, data):
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def png(width, height, depth, colour, rows, trns=None):
    """rows: lists of samples (grey, or grey and alpha interleaved)."""
    fmt = ">" + ("B" if depth == 8 else "H")
    raw = b"".join(b"\0" + struct.pack(fmt[0] + fmt[1] * len(r), *r) for r in rows)
    ihdr = struct.pack(">IIBBBBB", width, height, depth, colour, 0, 0, 0)
    out = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr)
    if trns is not None:
        out += chunk(b"tRNS", struct.pack(">H", trns))
    return out + chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b"")


# ---- TIFF ----------------------------------------------------------------------------------

SHORT, ASCII, LONG, DOUBLE, LONG8 = 3, 2, 4, 12, 16
TYPE_SIZE = {1: 1, ASCII: 1, SHORT: 2, LONG: 4, DOUBLE: 8, LONG8: 8}
TYPE_CODE = {SHORT: "H", LONG: "I", DOUBLE: "d", LONG8: "Q"}


def tiff(width, height, sample_format, bits, values, extra=(), big_endian=False, big=False, deflate=False):
    """One strip of one band; `extra` holds (tag, type, values) entries (ASCII: a str)."""
    e = ">" if big_endian else "<"
    code = {(1, 8): "B", (1, 16): "H", (1, 32): "I", (2, 8): "b", (2, 16): "h", (2, 32): "i", (3, 32): "f", (3, 64): "d"}
    data = struct.pack(e + code[(sample_format, bits)] * len(values), *values)
    if deflate:
        data = zlib.compress(data, 9)
    header_len = 16 if big else 8
    strip_offset = header_len
    entries = [
        (256, LONG, [width]),
        (257, LONG, [height]),
        (258, SHORT, [bits]),
        (259, SHORT, [8 if deflate else 1]),
        (262, SHORT, [1]),
        (273, LONG8 if big else LONG, [strip_offset]),
        (277, SHORT, [1]),
        (278, LONG, [height]),
        (279, LONG8 if big else LONG, [len(data)]),
        (339, SHORT, [sample_format]),
    ] + list(extra)
    entries.sort(key=lambda t: t[0])
    ifd_offset = header_len + len(data)
    ifd_offset += ifd_offset % 2
    entry_len, count_len, inline = (20, 8, 8) if big else (12, 2, 4)
    after_ifd = ifd_offset + count_len + entry_len * len(entries) + (8 if big else 4)
    ifd = struct.pack(e + ("Q" if big else "H"), len(entries))
    overflow = b""
    for tag, kind, vals in entries:
        if kind == ASCII:
            payload, count = vals.encode() + b"\0", len(vals) + 1
        else:
            payload, count = struct.pack(e + TYPE_CODE[kind] * len(vals), *vals), len(vals)
        if len(payload) <= inline:
            field = payload + b"\0" * (inline - len(payload))
        else:
            field = struct.pack(e + ("Q" if big else "I"), after_ifd + len(overflow))
            overflow += payload + b"\0" * (len(payload) % 2)
        ifd += struct.pack(e + "HH" + ("Q" if big else "I"), tag, kind, count) + field
    ifd += b"\0" * (8 if big else 4)
    if big:
        head = (b"MM" if big_endian else b"II") + struct.pack(e + "HHHQ", 43, 8, 0, ifd_offset)
    else:
        head = (b"MM" if big_endian else b"II") + struct.pack(e + "HI", 42, ifd_offset)
    body = head + data
    body += b"\0" * (ifd_offset - len(body))
    return body + ifd + overflow


def geokeys(raster_type):
    # Header (version 1, revision 1.0, one key), then GTRasterTypeGeoKey (1025).
    return [1, 1, 0, 1, 1025, 0, 1, raster_type]


# ---- the seeds -----------------------------------------------------------------------------


def seeds():
    ramp = [float(k) * 0.5 - 1.0 for k in range(12)]
    yield "npy_f4_c.npy", NO_HINTS + npy("<f4", (3, 4), ramp)
    yield "npy_f8_fortran.npy", NO_HINTS + npy("<f8", (2, 3), ramp[:6], fortran=True)
    yield "npy_i2_big_endian.npy", NO_HINTS + npy(">i2", (3, 2), [-3, 0, 7, 300, -32768, 32767])
    yield "npy_u2_v2.npy", NO_HINTS + npy("<u2", (2, 2), [0, 1, 65535, 40000], version=2)
    yield "npy_u1.npy", NO_HINTS + npy("|u1", (2, 3), [0, 1, 2, 3, 4, 255])
    yield "png_grey8.png", NO_HINTS + png(4, 3, 8, 0, [[0, 10, 20, 30], [40, 50, 60, 70], [80, 90, 100, 255]])
    yield "png_grey16.png", NO_HINTS + png(3, 3, 16, 0, [[0, 1000, 65535], [2, 3, 4], [5, 60000, 7]])
    yield "png_grey_alpha8.png", NO_HINTS + png(2, 2, 8, 4, [[5, 255, 6, 255], [7, 255, 8, 255]])
    yield "png_grey8_trns.png", NO_HINTS + png(3, 2, 8, 0, [[1, 2, 3], [4, 5, 6]], trns=200)
    yield "tiff_u8_le.tif", NO_HINTS + tiff(3, 2, 1, 8, [1, 2, 3, 4, 5, 6])
    yield "tiff_f32_be.tif", NO_HINTS + tiff(2, 3, 3, 32, [0.5, -1.5, 2.25, 3.0, 1e10, -7.0], big_endian=True)
    yield "tiff_i16_deflate.tif", NO_HINTS + tiff(3, 3, 2, 16, [-5, 0, 5, 10, 15, 20, -25, 30, 35], deflate=True)
    yield "bigtiff_u16.tif", NO_HINTS + tiff(2, 2, 1, 16, [100, 200, 300, 400], big=True)
    scale_tie = [
        (33550, DOUBLE, [30.0, 30.0, 0.0]),
        (33922, DOUBLE, [0.0, 0.0, 0.0, 500000.0, 4100000.0, 0.0]),
        (34735, SHORT, geokeys(2)),
        (42113, ASCII, "-9999"),
    ]
    yield "geotiff_f64_scale_tiepoint.tif", NO_HINTS + tiff(3, 2, 3, 64, ramp[:6], extra=scale_tie)
    matrix = [10.0, 0.0, 0.0, 100.0, 0.0, -5.0, 0.0, 200.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]
    yield "geotiff_i32_transform.tif", NO_HINTS + tiff(2, 2, 2, 32, [-1, 2, -3, 4], extra=[(34264, DOUBLE, matrix)])
    yield "raw_f32.bin", hints(3, 2, "f32") + struct.pack("<6f", 4.0, 5.0, 6.0, 1.0, 2.0, 3.0)
    yield "raw_f64.bin", hints(2, 2, "f64") + struct.pack("<4d", 0.1, -0.2, 3e100, -4e-100)
    grid = {"nx": 3, "ny": 2, "values": [0, 1, 4, 1, 2.5, -5e-3]}
    yield "grid.json", NO_HINTS + json.dumps(grid).encode()
    yield "grid_spaces.json", NO_HINTS + b" \n\t" + json.dumps({"values": [1, 2, 3, 4], "ny": 2, "nx": 2}).encode()


def main():
    os.makedirs(OUT, exist_ok=True)
    for name, data in seeds():
        assert len(data) < 4096, name
        with open(os.path.join(OUT, name), "wb") as f:
            f.write(data)
        print(f"{len(data):5d}  {name}")


if __name__ == "__main__":
    main()
