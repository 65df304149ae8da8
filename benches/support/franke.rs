//! Franke's test function, as a meval string and as a native closure, and a fixed scatter of
//! points to evaluate it at, shared by the benchmarks and examples/profile_refine.rs.

use meshfit::geom::Point;

/// Franke's function as meval text.
#[allow(dead_code)] // not every bench that includes this file uses it
pub const FRANKE: &str = "0.75*exp(-((9*x-2)^2 + (9*y-2)^2)/4) + 0.75*exp(-((9*x+1)^2)/49 - (9*y+1)/10) \
                          + 0.5*exp(-((9*x-7)^2 + (9*y-3)^2)/4) - 0.2*exp(-((9*x-4)^2) - (9*y-7)^2)";

/// Franke's function, natively.
pub fn franke(x: f64, y: f64) -> f64 {
    let (a, b) = (9.0 * x, 9.0 * y);
    0.75 * (-((a - 2.0).powi(2) + (b - 2.0).powi(2)) / 4.0).exp()
        + 0.75 * (-(a + 1.0).powi(2) / 49.0 - (b + 1.0) / 10.0).exp()
        + 0.5 * (-((a - 7.0).powi(2) + (b - 3.0).powi(2)) / 4.0).exp()
        - 0.2 * (-(a - 4.0).powi(2) - (b - 7.0).powi(2)).exp()
}

/// `n` points scattered over [0, 1]² in no order a mesh knows: a Weyl sequence, the same on
/// every run.
#[allow(dead_code)] // not every bench that includes this file uses it
pub fn scatter(n: u64) -> Vec<Point> {
    (0..n)
        .map(|k| {
            Point::new(
                (k as f64 * 0.618_033_988_749_894_9).fract(),
                (k as f64 * 0.754_877_666_246_692_7).fract(),
            )
        })
        .collect()
}
