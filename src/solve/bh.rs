//! A soft magnetic material's B–H curve: H as a monotone function of |B|.
//!
//! The table's points are joined by the monotone piecewise cubic Hermite interpolant of
//! Fritsch and Carlson (1980), the scheme of MATLAB's and SciPy's `pchip`: H(B) rises wherever
//! the table rises, so the reluctivity ν = H/B stays positive and Newton's Jacobian, whose
//! stiffness along B is dH/dB, stays positive definite. Past the last point the curve goes on
//! with the slope of vacuum, dB/dH = μ0, as FEMM extends its curves.

use super::physics::MU_0;

/// A material law H(|B|), strictly increasing from H(0) = 0: what a nonlinear region's
/// stiffness and energy are computed from. [`BhCurve`] is a table's; tests use closed forms.
pub trait Curve: Send + Sync + std::fmt::Debug {
    /// H at |B| = `b` (A/m) and dH/dB there.
    fn h(&self, b: f64) -> (f64, f64);

    /// The energy density ∫₀^b H dB (J/m³).
    fn energy(&self, b: f64) -> f64;

    /// The reluctivity ν = H/B at |B| = `b` (its limit dH/dB at b = 0) and dH/dB.
    fn nu(&self, b: f64) -> (f64, f64) {
        let (h, dh) = self.h(b);
        if b == 0.0 { (dh, dh) } else { (h / b, dh) }
    }
}

/// Why a table is not a usable B–H curve; `index` is the entry at fault.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CurveError {
    /// Fewer than two points.
    #[error("a B–H table needs at least two points, [0, 0] and one more")]
    TooShort,
    /// The first point is not [0, 0].
    #[error("the first point must be [0, 0]")]
    Origin,
    /// A value is not finite.
    #[error("[{h}, {b}] is not a pair of finite numbers")]
    NotFinite {
        /// The entry.
        index: usize,
        /// Its H.
        h: f64,
        /// Its B.
        b: f64,
    },
    /// H or B does not increase strictly from the previous entry.
    #[error("[{h}, {b}] does not increase strictly from the entry before it: H and B must both rise")]
    NotMonotone {
        /// The entry.
        index: usize,
        /// Its H.
        h: f64,
        /// Its B.
        b: f64,
    },
}

impl CurveError {
    /// The table entry at fault, if one is.
    pub fn index(&self) -> Option<usize> {
        match self {
            CurveError::TooShort => None,
            CurveError::Origin => Some(0),
            CurveError::NotFinite { index, .. } | CurveError::NotMonotone { index, .. } => Some(*index),
        }
    }
}

/// H(B) through a table of (H, B) points, with its slope and the energy density ∫₀ᴮ H dB.
#[derive(Debug, Clone, PartialEq)]
pub struct BhCurve {
    /// B of each point (T).
    b: Vec<f64>,
    /// H of each point (A/m).
    h: Vec<f64>,
    /// dH/dB at each point, as the interpolant has it.
    slope: Vec<f64>,
    /// ∫₀^{bᵢ} H dB at each point (J/m³).
    energy: Vec<f64>,
}

/// The three-point Gauss–Legendre rule on [0, 1]: exact for the cubic pieces of H.
const GAUSS3: [(f64, f64); 3] =
    [(0.112_701_665_379_258_3, 5.0 / 18.0), (0.5, 8.0 / 18.0), (0.887_298_334_620_741_7, 5.0 / 18.0)];

impl BhCurve {
    /// The curve through `points`, each [H in A/m, B in T], from [0, 0] with both strictly
    /// increasing.
    ///
    /// # Errors
    /// [`CurveError`] naming the first entry at fault.
    pub fn new(points: &[[f64; 2]]) -> Result<Self, CurveError> {
        if points.len() < 2 {
            return Err(CurveError::TooShort);
        }
        for (index, &[h, b]) in points.iter().enumerate() {
            if !(h.is_finite() && b.is_finite()) {
                return Err(CurveError::NotFinite { index, h, b });
            }
        }
        if points[0] != [0.0, 0.0] {
            return Err(CurveError::Origin);
        }
        for (index, pair) in points.windows(2).enumerate() {
            let ([h0, b0], [h1, b1]) = (pair[0], pair[1]);
            if !(h1 > h0 && b1 > b0) {
                return Err(CurveError::NotMonotone { index: index + 1, h: h1, b: b1 });
            }
        }
        let (h, b): (Vec<f64>, Vec<f64>) = points.iter().map(|&[h, b]| (h + 0.0, b + 0.0)).unzip();
        let slope = pchip_slopes(&b, &h);
        let mut curve = Self { b, h, slope, energy: Vec::new() };
        let mut energy = vec![0.0; curve.b.len()];
        for i in 1..curve.b.len() {
            energy[i] = energy[i - 1] + curve.integral(i - 1, curve.b[i]);
        }
        curve.energy = energy;
        Ok(curve)
    }

    /// The segment holding `b` (≥ 0): `Some(i)` for [bᵢ, bᵢ₊₁], `None` past the last point.
    fn segment(&self, b: f64) -> Option<usize> {
        let last = self.b.len() - 1;
        if b >= self.b[last] {
            return None;
        }
        Some(self.b.partition_point(|&x| x <= b).saturating_sub(1).min(last - 1))
    }

    /// H and dH/dB on segment `i` at `b`.
    fn hermite(&self, i: usize, b: f64) -> (f64, f64) {
        let (b0, b1) = (self.b[i], self.b[i + 1]);
        let w = b1 - b0;
        let t = (b - b0) / w;
        let (h0, h1, m0, m1) = (self.h[i], self.h[i + 1], self.slope[i] * w, self.slope[i + 1] * w);
        let (t2, t3) = (t * t, t * t * t);
        let h = (2.0 * t3 - 3.0 * t2 + 1.0) * h0
            + (t3 - 2.0 * t2 + t) * m0
            + (-2.0 * t3 + 3.0 * t2) * h1
            + (t3 - t2) * m1;
        let dh = (6.0 * t2 - 6.0 * t) * h0
            + (3.0 * t2 - 4.0 * t + 1.0) * m0
            + (-6.0 * t2 + 6.0 * t) * h1
            + (3.0 * t2 - 2.0 * t) * m1;
        (h, dh / w)
    }

    /// ∫ H dB over segment `i` from its start to `b`.
    fn integral(&self, i: usize, b: f64) -> f64 {
        let (b0, span) = (self.b[i], b - self.b[i]);
        GAUSS3.iter().map(|&(x, w)| w * self.hermite(i, b0 + x * span).0).sum::<f64>() * span
    }
}

impl Curve for BhCurve {
    /// H at |B| = `b` and dH/dB there.
    fn h(&self, b: f64) -> (f64, f64) {
        let b = b.abs();
        match self.segment(b) {
            Some(i) => self.hermite(i, b),
            None => {
                let last = self.b.len() - 1;
                (self.h[last] + (b - self.b[last]) / MU_0, 1.0 / MU_0)
            }
        }
    }

    /// The reluctivity ν = H/B at |B| = `b` (its limit dH/dB at b = 0) and dH/dB.
    fn nu(&self, b: f64) -> (f64, f64) {
        let b = b.abs();
        let (h, dh) = self.h(b);
        // Below a millionth of the first point's B, H/B is its limit to rounding.
        if b <= 1e-6 * self.b[1] { (self.slope[0], self.slope[0]) } else { (h / b, dh) }
    }

    /// The energy density ∫₀^b H dB (J/m³) at |B| = `b`.
    fn energy(&self, b: f64) -> f64 {
        let b = b.abs();
        match self.segment(b) {
            Some(i) => self.energy[i] + self.integral(i, b),
            None => {
                let last = self.b.len() - 1;
                let d = b - self.b[last];
                self.energy[last] + self.h[last] * d + d * d / (2.0 * MU_0)
            }
        }
    }
}

/// Fritsch–Carlson slopes of the monotone cubic through (xᵢ, yᵢ), x and y strictly
/// increasing: the weighted harmonic mean of the neighbouring secants inside (Fritsch and
/// Butland's form, as SciPy's `PchipInterpolator`), and the one-sided three-point formula,
/// clipped into [0, 3·secant], at the ends.
fn pchip_slopes(x: &[f64], y: &[f64]) -> Vec<f64> {
    let n = x.len();
    let w: Vec<f64> = x.windows(2).map(|p| p[1] - p[0]).collect();
    let d: Vec<f64> = (0..n - 1).map(|i| (y[i + 1] - y[i]) / w[i]).collect();
    if n == 2 {
        return vec![d[0]; 2];
    }
    let mut m = vec![0.0; n];
    for i in 1..n - 1 {
        let (w1, w2) = (2.0 * w[i] + w[i - 1], w[i] + 2.0 * w[i - 1]);
        m[i] = (w1 + w2) / (w1 / d[i - 1] + w2 / d[i]);
    }
    let end = |w0: f64, w1: f64, d0: f64, d1: f64| {
        let m = ((2.0 * w0 + w1) * d0 - w0 * d1) / (w0 + w1);
        m.clamp(0.0, 3.0 * d0)
    };
    m[0] = end(w[0], w[1], d[0], d[1]);
    m[n - 1] = end(w[n - 2], w[n - 3], d[n - 2], d[n - 3]);
    // A zero end slope would make ν(0) zero; the secant keeps the curve strictly rising.
    for (k, s) in [(0, d[0]), (n - 1, d[n - 2])] {
        if m[k] <= 0.0 {
            m[k] = s;
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const STEEL: [[f64; 2]; 5] = [[0.0, 0.0], [100.0, 0.6], [300.0, 1.1], [1000.0, 1.45], [10000.0, 1.8]];

    #[test]
    fn the_curve_passes_through_its_points_and_extends_with_the_slope_of_vacuum() {
        let c = BhCurve::new(&STEEL).unwrap();
        for [h, b] in STEEL {
            assert!((c.h(b).0 - h).abs() <= 1e-9 * h.max(1.0), "H({b}) = {} ≠ {h}", c.h(b).0);
        }
        let (h, dh) = c.h(2.8);
        assert!((h - (10000.0 + 1.0 / MU_0)).abs() < 1e-6 * h);
        assert_eq!(dh, 1.0 / MU_0);
    }

    #[test]
    fn the_energy_is_the_integral_of_h() {
        let c = BhCurve::new(&STEEL).unwrap();
        // A fine trapezoid rule against the closed form, inside the table and past it.
        for b_end in [0.3, 1.1, 1.7, 2.5] {
            let n = 200_000;
            let step = b_end / n as f64;
            let trapezoid: f64 =
                (0..n).map(|k| 0.5 * (c.h(k as f64 * step).0 + c.h((k + 1) as f64 * step).0) * step).sum();
            assert!((c.energy(b_end) - trapezoid).abs() < 1e-6 * trapezoid, "{b_end}");
        }
    }

    #[test]
    fn bad_tables_name_their_entry() {
        assert_eq!(BhCurve::new(&[[0.0, 0.0]]), Err(CurveError::TooShort));
        assert_eq!(BhCurve::new(&[[1.0, 0.0], [2.0, 1.0]]).unwrap_err().index(), Some(0));
        let e = BhCurve::new(&[[0.0, 0.0], [100.0, 0.6], [90.0, 1.1]]).unwrap_err();
        assert_eq!(e, CurveError::NotMonotone { index: 2, h: 90.0, b: 1.1 });
        let e = BhCurve::new(&[[0.0, 0.0], [100.0, 0.6], [200.0, 0.6]]).unwrap_err();
        assert_eq!(e.index(), Some(2));
        let e = BhCurve::new(&[[0.0, 0.0], [f64::NAN, 0.6]]).unwrap_err();
        assert_eq!(e.index(), Some(1));
    }

    proptest! {
        #[test]
        fn h_rises_and_nu_stays_positive_between_any_two_flux_densities(
            steps in proptest::collection::vec((1.0f64..1000.0, 0.01f64..1.0), 1..8),
            b1 in 0.0f64..4.0,
            b2 in 0.0f64..4.0,
        ) {
            let mut points = vec![[0.0, 0.0]];
            for (dh, db) in steps {
                let [h, b] = *points.last().unwrap();
                points.push([h + dh, b + db]);
            }
            let c = BhCurve::new(&points).unwrap();
            let (lo, hi) = if b1 < b2 { (b1, b2) } else { (b2, b1) };
            prop_assert!(c.h(lo).0 <= c.h(hi).0 + 1e-9 * c.h(hi).0.abs());
            prop_assert!(c.h(hi).1 >= 0.0);
            prop_assert!(c.nu(hi).0 > 0.0);
            prop_assert!(c.energy(lo) <= c.energy(hi));
        }
    }
}
