//! Holes in a raster (its nodata samples) filled from their neighbours, for data that must be
//! whole to be meshed: a DEM's voids and collars.
//!
//! Layer by layer from the data inwards: each hole next to a known sample (of its eight
//! neighbours) takes the mean of those known before its layer, then its layer becomes known.
//! A hole's value thus depends only on the samples around it, not on the order of a scan
//! (the same bytes on every machine), and a hole n samples from the data is filled in the nth
//! layer: O(samples) in all.

/// Fills the samples of `values` (row-major, `[nx, ny]`) for which `hole` is true, in place,
/// and returns which were; `None` when every sample is a hole.
pub fn fill_holes(values: &mut [f64], [nx, ny]: [usize; 2], hole: impl Fn(f64) -> bool) -> Option<Vec<bool>> {
    let holes: Vec<bool> = values.iter().map(|&v| hole(v)).collect();
    if !holes.contains(&true) {
        return Some(holes);
    }
    if !holes.contains(&false) {
        return None;
    }
    let mut known: Vec<bool> = holes.iter().map(|h| !h).collect();
    let neighbours = |k: usize| {
        let (i, j) = ((k % nx) as isize, (k / nx) as isize);
        (-1..=1isize)
            .flat_map(move |dj| (-1..=1isize).map(move |di| (i + di, j + dj)))
            .filter(move |&(a, b)| (a, b) != (i, j) && a >= 0 && b >= 0 && a < nx as isize && b < ny as isize)
            .map(move |(a, b)| b as usize * nx + a as usize)
    };
    let mut layer: Vec<usize> =
        (0..values.len()).filter(|&k| holes[k] && neighbours(k).any(|n| known[n])).collect();
    let mut filled = Vec::with_capacity(layer.len());
    while !layer.is_empty() {
        filled.clear();
        for &k in &layer {
            let (sum, count) =
                neighbours(k).filter(|&n| known[n]).fold((0.0, 0u32), |(s, c), n| (s + values[n], c + 1));
            filled.push(sum / f64::from(count));
        }
        for (&k, &v) in layer.iter().zip(&filled) {
            values[k] = v;
            known[k] = true;
        }
        let mut next: Vec<usize> = layer.iter().flat_map(|&k| neighbours(k)).filter(|&n| !known[n]).collect();
        next.sort_unstable();
        next.dedup();
        layer = next;
    }
    Some(holes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_hole_takes_the_mean_of_its_known_neighbours_layer_by_layer() {
        // 5 × 1 with a hole of three in the middle: 1, _, _, _, 9.
        let hole = |v: f64| v == -1.0;
        let mut values = vec![1.0, -1.0, -1.0, -1.0, 9.0];
        let filled = fill_holes(&mut values, [5, 1], hole).unwrap();
        assert_eq!(filled, [false, true, true, true, false]);
        // Layer 1: the two next to the data; layer 2: the middle, from both.
        assert_eq!(values, [1.0, 1.0, 5.0, 9.0, 9.0]);
    }

    #[test]
    fn the_result_does_not_depend_on_the_scan_and_all_holes_is_none() {
        // A plane with a square void: the fill is symmetric where the data are.
        let shape = [7, 7];
        let mut values: Vec<f64> = (0..49).map(|k| f64::from((k % 7) as u8 + (k / 7) as u8)).collect();
        for j in 2..5 {
            for i in 2..5 {
                values[j * 7 + i] = f64::NAN;
            }
        }
        let mut transposed = values.clone();
        for j in 0..7 {
            for i in 0..7 {
                transposed[i * 7 + j] = values[j * 7 + i];
            }
        }
        fill_holes(&mut values, shape, f64::is_nan).unwrap();
        fill_holes(&mut transposed, shape, f64::is_nan).unwrap();
        for j in 0..7 {
            for i in 0..7 {
                assert_eq!(values[j * 7 + i], transposed[i * 7 + j]);
            }
        }
        assert!(values.iter().all(|v| v.is_finite()));
        // The void's centre, (3, 3), is the plane's value there by symmetry.
        assert_eq!(values[3 * 7 + 3], 6.0);
        assert!(fill_holes(&mut [f64::NAN; 4], [2, 2], f64::is_nan).is_none());
    }
}
