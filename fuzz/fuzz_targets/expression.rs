//! `Expression::parse` on arbitrary text (at most 4096 bytes, invalid UTF-8 replaced).
//!
//! Checks that parsing never panics; that an error's column is 1-based and at most one past
//! the last character, and that the error displays; and that a parsed expression gives the
//! same bits from `eval_xy` and from `eval_many` (batches of 16 and a partial batch) at
//! ordinary, signed-zero, huge, tiny, infinite and NaN points, any NaN matching any NaN.
#![no_main]

use libfuzzer_sys::fuzz_target;
use meshfit::geom::Point;
use meshfit::source::Expression;

/// Longest text tried: the service's default limit is 4096 characters.
const MAX_LEN: usize = 4096;

/// Points to evaluate at: 21 of them, so `eval_many` runs one full batch and a partial one.
const POINTS: [(f64, f64); 21] = [
    (0.0, 0.0),
    (1.0, 1.0),
    (0.5, 0.25),
    (-0.0, 0.0),
    (0.0, -0.0),
    (-1.0, 2.0),
    (3.0, -7.5),
    (0.1, 0.7),
    (1e-300, -1e-300),
    (5e-324, 1.0),
    (1e300, 1e300),
    (-1e308, 2.0),
    (f64::INFINITY, 1.0),
    (1.0, f64::NEG_INFINITY),
    (f64::NAN, 0.5),
    (0.5, f64::NAN),
    (std::f64::consts::PI, std::f64::consts::E),
    (-0.5, -0.5),
    (2.0, 0.5),
    (1e15, -1e-15),
    (0.999_999_999_999_999_9, 1.000_000_000_000_000_2),
];

fn same(a: f64, b: f64) -> bool {
    a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan())
}

fuzz_target!(|data: &[u8]| {
    if data.len() > MAX_LEN {
        return;
    }
    let text = String::from_utf8_lossy(data);
    match Expression::parse(&text) {
        Err(e) => {
            let end = text.chars().count() + 1;
            assert!((1..=end).contains(&e.column), "column {} outside 1..={end} for {text:?}: {e}", e.column);
            let _ = e.to_string();
        }
        Ok(f) => {
            assert_eq!(f.text(), text, "text() is not the parsed text");
            let points: Vec<Point> = POINTS.iter().map(|&(x, y)| Point::new(x, y)).collect();
            let mut many = vec![0.0; points.len()];
            f.eval_many(&points, &mut many);
            for (p, &m) in points.iter().zip(&many) {
                let one = f.eval_xy(p.x, p.y);
                assert!(same(one, m), "{text:?} at ({:?}, {:?}): eval_xy {one:?}, eval_many {m:?}", p.x, p.y);
            }
            // A batch that starts at another point gives each point the same bits again.
            let mut tail = vec![0.0; points.len() - 3];
            f.eval_many(&points[3..], &mut tail);
            for (k, (&t, &m)) in tail.iter().zip(&many[3..]).enumerate() {
                assert!(same(t, m), "{text:?} at point {}: {t:?} in one batch, {m:?} in another", k + 3);
            }
        }
    }
});
