//! `decode_grid` on arbitrary bytes: the one decoder of every grid file the service takes
//! (.npy, PNG 8/16-bit, TIFF/GeoTIFF, raw f32/f64, JSON).
//!
//! Input layout: byte 0 says which hints are given (bit 0 nx, bit 1 ny, bits 2–3 the dtype:
//! 1 f32, 2 f64, else none), bytes 1 and 2 are nx and ny (254 and 255 stand for 2^32 + 1
//! and `usize::MAX`, to reach the size arithmetic), and the rest is the file. The seeds in
//! `fuzz/seeds/grid_file/` carry this 3-byte prefix (see `fuzz/seeds/make_grid_seeds.py`).
//!
//! Checks that nothing panics or allocates past the limit (libFuzzer's RSS limit), and for a
//! decoded grid: nx, ny ≥ 2 and nx·ny within `max_points`; every value finite and no -0.0;
//! the format is the one the first bytes name; raw data had all three hints and exactly
//! nx·ny samples; only a TIFF gives a domain; and the same file with a limit one point below
//! its size is refused with `TooManyPoints`. A refusal must display, and a `Corrupt` detail
//! stays short.
//!
//! With `GRID_FILE_VERBOSE=1` in the environment each input's outcome is printed, to check
//! that the seeds decode: `fuzz/target/x86_64-unknown-linux-gnu/release/grid_file seeds/grid_file/*`.
#![no_main]

use libfuzzer_sys::fuzz_target;
use meshfit::source::{Encoding, GridFileError, GridFileKind, GridHints, RawType, decode_grid};
use std::sync::OnceLock;

fn verbose() -> bool {
    static VERBOSE: OnceLock<bool> = OnceLock::new();
    *VERBOSE.get_or_init(|| std::env::var_os("GRID_FILE_VERBOSE").is_some_and(|v| v == "1"))
}

/// The largest grid decoded: 2^16 points.
const MAX_POINTS: usize = 1 << 16;

fn size(byte: u8) -> usize {
    match byte {
        255 => usize::MAX,
        254 => (1 << 32) + 1,
        n => usize::from(n),
    }
}

fuzz_target!(|data: &[u8]| {
    let Some((&[flags, nx, ny], file)) = data.split_first_chunk::<3>() else { return };
    let hints = GridHints {
        nx: (flags & 1 != 0).then(|| size(nx)),
        ny: (flags & 2 != 0).then(|| size(ny)),
        dtype: match (flags >> 2) & 3 {
            1 => Some(RawType::F32),
            2 => Some(RawType::F64),
            _ => None,
        },
        encoding: match (flags >> 4) & 3 {
            1 => Some(Encoding::TerrainRgb),
            2 => Some(Encoding::Terrarium),
            _ => None,
        },
    };
    let decoded = match decode_grid(file, &hints, MAX_POINTS) {
        Ok(d) => d,
        Err(e) => {
            let message = e.to_string();
            if verbose() {
                eprintln!("refused: {message}");
            }
            if let GridFileError::Corrupt { detail, .. } = &e {
                assert!(detail.chars().count() <= 301, "a detail of {} characters", detail.chars().count());
            }
            assert!(!message.is_empty());
            return;
        }
    };
    let g = &decoded.grid;
    if verbose() {
        eprintln!("decoded: {} {} x {}, domain {:?}", decoded.kind, g.nx(), g.ny(), decoded.domain);
    }
    let points = g.nx() * g.ny();
    assert!(g.nx() >= 2 && g.ny() >= 2, "{} x {}", g.nx(), g.ny());
    assert!(points <= MAX_POINTS, "{points} points above the limit");
    for j in 0..g.ny() {
        for (i, &v) in g.row(j).iter().enumerate() {
            assert!(v.is_finite(), "value {v} at ({i}, {j})");
            assert!(v.to_bits() != (-0.0f64).to_bits(), "-0.0 at ({i}, {j})");
        }
    }
    let starts = |m: &[u8]| file.starts_with(m);
    let expected = if starts(b"\x93NUMPY") {
        Some(GridFileKind::Npy)
    } else if starts(b"\x89PNG\r\n\x1a\n") {
        Some(GridFileKind::Png)
    } else if starts(b"II*\0") || starts(b"MM\0*") || starts(b"II+\0") || starts(b"MM\0+") {
        Some(GridFileKind::Tiff)
    } else {
        None
    };
    if let Some(kind) = expected {
        assert_eq!(decoded.kind, kind, "the first bytes name another format");
    }
    match decoded.kind {
        GridFileKind::Raw => {
            let (Some(hx), Some(hy), Some(t)) = (hints.nx, hints.ny, hints.dtype) else {
                panic!("raw data decoded without all three hints: {hints:?}");
            };
            assert_eq!((g.nx(), g.ny()), (hx, hy), "raw grid of another shape than the hints");
            assert_eq!(file.len(), points * t.size(), "raw grid of another length");
        }
        GridFileKind::Json => {
            assert_eq!(file.iter().find(|b| !b" \t\r\n".contains(b)), Some(&b'{'));
        }
        _ => {}
    }
    if decoded.domain.is_some() {
        assert_eq!(decoded.kind, GridFileKind::Tiff, "only a GeoTIFF gives a domain");
    }
    match decode_grid(file, &hints, points - 1) {
        Err(GridFileError::TooManyPoints { requested, allowed, .. }) => {
            assert_eq!((requested, allowed), (points as u64, points - 1));
        }
        other => panic!("{points} points with a limit of {}: {other:?}", points - 1),
    }
});
