//! The colour map that every picture and coloured format shares: viridis (perceptually
//! uniform, readable in grey and by colour-blind readers), from the `colorous` crate.

/// The colour of `z` on the scale from `lo` to `hi` (clamped; a flat range is mid-scale).
pub fn of(z: f64, lo: f64, hi: f64) -> [u8; 3] {
    let t = if hi > lo { ((z - lo) / (hi - lo)).clamp(0.0, 1.0) } else { 0.5 };
    colorous::VIRIDIS.eval_continuous(t).as_array()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_scale_runs_from_dark_to_light_and_clamps() {
        let (lo, hi) = (of(-2.0, -2.0, 3.0), of(3.0, -2.0, 3.0));
        let brightness = |c: [u8; 3]| c.iter().map(|&v| u32::from(v)).sum::<u32>();
        assert!(brightness(lo) < brightness(hi));
        assert_eq!(of(-9.0, -2.0, 3.0), lo);
        assert_eq!(of(9.0, -2.0, 3.0), hi);
        assert_eq!(of(1.0, 1.0, 1.0), of(0.5, 0.0, 1.0));
    }
}
