//! The 6-point, degree-4 quadrature rule on a triangle that every integral in `solve` uses.

/// Barycentric coordinates and weights (summing to 1) of the 6-point rule of degree 4.
///
/// The rule integrates every polynomial of degree ≤ 4 exactly, once the weighted sum is
/// multiplied by the triangle's area. All six points lie strictly inside the triangle, so a
/// coefficient that jumps along a mesh edge is never sampled on that edge.
// Dunavant, "High degree efficient symmetrical Gaussian quadrature rules for the triangle",
// Int. J. Numer. Meth. Eng. 21 (1985), rule 4.
pub(crate) const RULE: [([f64; 3], f64); 6] = {
    const A1: f64 = 0.445_948_490_915_965;
    const B1: f64 = 1.0 - 2.0 * A1;
    const W1: f64 = 0.223_381_589_678_011;
    const A2: f64 = 0.091_576_213_509_771;
    const B2: f64 = 1.0 - 2.0 * A2;
    const W2: f64 = 0.109_951_743_655_322;
    [
        ([B1, A1, A1], W1),
        ([A1, B1, A1], W1),
        ([A1, A1, B1], W1),
        ([B2, A2, A2], W2),
        ([A2, B2, A2], W2),
        ([A2, A2, B2], W2),
    ]
};

#[cfg(test)]
mod tests {
    use super::RULE;

    /// ∫ λ₀^i λ₁^j λ₂^k over the reference triangle divided by its area: 2 i! j! k! / (i+j+k+2)!.
    fn exact_monomial(i: u32, j: u32, k: u32) -> f64 {
        let fact = |n: u32| (1..=n).map(f64::from).product::<f64>();
        2.0 * fact(i) * fact(j) * fact(k) / fact(i + j + k + 2)
    }

    #[test]
    fn the_rule_integrates_every_monomial_of_degree_at_most_four_exactly() {
        for i in 0..=4 {
            for j in 0..=4 - i {
                for k in 0..=4 - i - j {
                    let got: f64 = RULE
                        .iter()
                        .map(|(l, w)| w * l[0].powi(i as i32) * l[1].powi(j as i32) * l[2].powi(k as i32))
                        .sum();
                    let want = exact_monomial(i, j, k);
                    assert!((got - want).abs() < 1e-14, "λ^({i},{j},{k}): {got} vs {want}");
                }
            }
        }
    }

    #[test]
    fn the_weights_sum_to_one_and_every_point_is_strictly_inside() {
        let sum: f64 = RULE.iter().map(|(_, w)| w).sum();
        assert!((sum - 1.0).abs() < 1e-14);
        for (l, _) in RULE {
            assert!(l.iter().all(|&c| c > 0.0));
            assert!((l.iter().sum::<f64>() - 1.0).abs() < 1e-15);
        }
    }
}
