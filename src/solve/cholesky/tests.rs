//! Tests of the sparse Cholesky: solutions that satisfy their system, assembly order, one
//! analysis for every matrix of a pattern, the refusal of a matrix that is not positive
//! definite, and the same bits from the AVX2 build as from the portable one.

use super::*;
use proptest::prelude::*;

type Entries = Vec<(usize, usize, f64)>;

/// A sparse SPD matrix as assembly entries (column, row, value) of its lower triangle: a
/// weighted graph Laplacian on random edges, one entry per edge end as a finite-element
/// assembly makes them (so duplicates), plus a positive diagonal.
fn laplacian(n: usize, edges: &[(usize, usize, f64)], shift: &[f64]) -> Entries {
    let mut entries: Entries = (0..n).map(|i| (i, i, shift[i])).collect();
    for &(a, b, w) in edges {
        let (a, b) = (a % n, b % n);
        if a == b {
            continue;
        }
        entries.extend([(a, a, w), (b, b, w), (a.min(b), a.max(b), -w)]);
    }
    entries
}

fn multiply(n: usize, entries: &[(usize, usize, f64)], x: &[f64]) -> Vec<f64> {
    let mut y = vec![0.0; n];
    for &(col, row, value) in entries {
        y[row] += value * x[col];
        if row != col {
            y[col] += value * x[row];
        }
    }
    y
}

/// A 2-D grid Laplacian, big enough for supernodes of many columns.
fn grid(side: usize) -> (usize, Entries) {
    let n = side * side;
    let mut edges = Vec::new();
    for r in 0..side {
        for c in 0..side {
            let v = r * side + c;
            if c + 1 < side {
                edges.push((v, v + 1, 1.0 + (v % 7) as f64 * 0.1));
            }
            if r + 1 < side {
                edges.push((v, v + side, 1.0 + (v % 5) as f64 * 0.2));
            }
        }
    }
    let shift: Vec<f64> = (0..n).map(|v| if v % side == 0 { 1.0 } else { 0.0 }).collect();
    (n, laplacian(n, &edges, &shift))
}

fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|v| v.to_bits()).collect()
}

proptest! {
    #[test]
    fn the_solution_satisfies_the_system(
        n in 1usize..60,
        edges in prop::collection::vec((0usize..60, 0usize..60, 0.1f64..10.0), 0..200),
        shift in prop::collection::vec(0.01f64..5.0, 60),
        b in prop::collection::vec(-10.0f64..10.0, 60),
    ) {
        let a = laplacian(n, &edges, &shift);
        let x = Analysis::new(n, &a).unwrap().solve(a.clone(), b[..n].to_vec()).unwrap();
        let ax = multiply(n, &a, &x);
        let scale = a.iter().fold(0.0f64, |m, e| m.max(e.2.abs())) * x.iter().fold(1.0f64, |m, v| m.max(v.abs()));
        for (got, want) in ax.iter().zip(&b[..n]) {
            prop_assert!((got - want).abs() <= 1e-10 * scale, "{got} vs {want}");
        }
    }

    /// Each value of P A Pᵀ is the sum of its entries in assembly order, to the bit: what a
    /// stable sort by position and a sum of each run gives.
    #[test]
    fn assembly_sums_each_place_in_assembly_order(
        entries in prop::collection::vec((0usize..6, 0usize..6, -1e3f64..1e3), 1..120),
    ) {
        let n = 6;
        let entries: Entries = entries.into_iter().map(|(c, r, v)| (c.min(r), c.max(r), v)).collect();
        let analysis = Analysis::new(n, &entries).unwrap();
        let mut sorted = entries.clone();
        sorted.sort_by_key(|&(col, row, _)| (col, row));
        let mut expected: Entries = Vec::new();
        for (col, row, value) in sorted {
            match expected.last_mut() {
                Some(last) if (last.0, last.1) == (col, row) => last.2 += value,
                _ => expected.push((col, row, value)),
            }
        }
        let values = analysis.assemble(&entries);
        prop_assert_eq!(values.len(), expected.len());
        for (col, row, value) in expected {
            let (i, j) = (analysis.inv[row], analysis.inv[col]);
            let lower = i.min(j);
            let place = (analysis.col_ptr[lower]..analysis.col_ptr[lower + 1])
                .find(|&k| analysis.row_idx[k] == i.max(j))
                .expect("every entry's place is in the pattern");
            prop_assert_eq!(values[place].to_bits(), value.to_bits(), "({}, {})", col, row);
        }
    }
}

#[test]
fn a_grid_laplacian_is_solved_to_rounding() {
    let (n, a) = grid(40);
    let analysis = Analysis::new(n, &a).unwrap();
    let s = analysis.supernodal();
    let widest = (0..s.n_supernodes()).map(|t| s.supernode_end()[t] - s.supernode_begin()[t]).max();
    assert!(widest > Some(2 * BLOCK_COLS), "the blocked paths are exercised: {widest:?}");
    let want: Vec<f64> = (0..n).map(|v| (v as f64 * 0.37).sin()).collect();
    let x = analysis.solve(a.clone(), multiply(n, &a, &want)).unwrap();
    for (got, want) in x.iter().zip(&want) {
        assert!((got - want).abs() < 1e-9, "{got} vs {want}");
    }
}

/// Newton's use: one analysis, then matrices of the same pattern with other values (step · A
/// plus a diagonal, still SPD), each solved as a fresh analysis of its own solves it.
#[test]
fn an_analysis_serves_every_matrix_of_its_pattern() {
    let (n, a) = grid(20);
    let analysis = Analysis::new(n, &a).unwrap();
    let b: Vec<f64> = (0..n).map(|v| (v as f64 * 0.11).cos()).collect();
    for step in 1..4 {
        let scaled: Entries = (a.iter().enumerate())
            .map(|(k, &(c, r, v))| {
                (c, r, v * step as f64 + if c == r { (k % (step + 2)) as f64 } else { 0.0 })
            })
            .collect();
        let reused = analysis.solve(scaled.clone(), b.clone()).unwrap();
        let fresh = Analysis::new(n, &scaled).unwrap().solve(scaled.clone(), b.clone()).unwrap();
        assert_eq!(bits(&reused), bits(&fresh));
        let residual = multiply(n, &scaled, &reused);
        assert!(residual.iter().zip(&b).all(|(got, want)| (got - want).abs() < 1e-9));
    }
}

#[test]
fn a_matrix_that_is_not_positive_definite_is_refused() {
    // [[1, 2], [2, 1]] has eigenvalues 3 and −1.
    let a = vec![(0, 0, 1.0), (0, 1, 2.0), (1, 1, 1.0)];
    let err = Analysis::new(2, &a).unwrap().solve(a, vec![1.0, 1.0]).err().unwrap();
    assert!(matches!(err, SolveError::NotPositiveDefinite { unknowns: 2, .. }), "{err:?}");
}

#[test]
fn the_avx2_build_gives_the_portable_bits() {
    let arch = pulp::Arch::new();
    if matches!(arch, pulp::Arch::Scalar) {
        return;
    }
    let (n, a) = grid(30);
    let analysis = Analysis::new(n, &a).unwrap();
    let lower = analysis.assemble(&a);
    let mut factors = [(); 2].map(|_| analysis.factorise(&lower).unwrap());
    for (factor, arch) in factors.iter_mut().zip([pulp::Arch::Scalar, arch]) {
        factor.values.fill(0.0);
        factor.factorise_on(arch, (&analysis.col_ptr, &analysis.row_idx, &lower)).unwrap();
    }
    assert_eq!(bits(&factors[0].values), bits(&factors[1].values));
    assert!(factors[0].values.iter().any(|&v| v != 0.0));
    // And the substitutions, on a right-hand side that is not the factor's own.
    let b: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin()).collect();
    let mut solutions = [b.clone(), b];
    for (x, arch) in solutions.iter_mut().zip([pulp::Arch::Scalar, arch]) {
        factors[0].solve_in_place_on(arch, x);
    }
    assert_eq!(bits(&solutions[0]), bits(&solutions[1]));
}
