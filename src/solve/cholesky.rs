//! Sparse Cholesky LLᵀ, supernodal, with dense kernels that give the same bits on every x86-64
//! machine.
//!
//! `faer` orders the matrix (approximate minimum degree) and finds the supernodes: runs of
//! columns of L that share one pattern below their diagonal block, stored as dense
//! column-major panels. The numbers are computed here, left-looking: a supernode gathers its
//! columns of A, subtracts the products of the panels below it that reach it, and factorises
//! its panel densely. faer has the same algorithm, but its dense kernels pick AVX2 or AVX-512
//! code and cache-sized blocks at run time, so its sums round differently on different CPUs.
//!
//! An [`Analysis`] holds what depends on the pattern alone: the ordering, the supernodes, and
//! where each assembled entry lands in the permuted matrix. Newton's iterations on one mesh
//! share it, and pay only assembly, factorisation and substitution each.
//!
//! # Determinism
//! Every entry of L is built by the same sequence of operations on every machine: each dot
//! product runs over k in increasing order as a chain of `f64::mul_add` (one rounding, the same
//! bits whether the CPU fuses it or libm computes it), and supernodes, descendants and columns
//! are visited in index order; each entry of A is the sum of its contributions in assembly
//! order. The AVX2+FMA build of the same code, chosen at run time when the
//! CPU has it, only runs four lanes of independent chains at once; it cannot change a bit. The
//! test `the_avx2_build_gives_the_portable_bits` holds it to that.

use super::error::SolveError;
use faer::Side;
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::linalg::cholesky::supernodal::SymbolicSupernodalCholesky;
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, SymbolicCholesky, SymbolicCholeskyRaw, SymmetricOrdering,
    factorize_symbolic_cholesky,
};
use faer::sparse::{FaerError, SymbolicSparseColMatRef};

/// What a factorisation needs of a matrix's pattern alone: the ordering P, the supernodes, the
/// lower triangle of P A Pᵀ in compressed columns, and where each assembled entry of A lands
/// there. Newton's iterations on one mesh assemble the same pattern in the same order, so one
/// analysis serves them all: the ordering and the sorts are paid once per mesh.
pub(super) struct Analysis {
    symbolic: SymbolicCholesky<usize>,
    /// The ordering, new → old and old → new.
    fwd: Vec<usize>,
    inv: Vec<usize>,
    /// P A Pᵀ's lower triangle: column pointers and row indices (sorted, each once).
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    /// For each entry in assembly order, its place among `row_idx`.
    slot: Vec<u32>,
}

/// A numeric factor P A Pᵀ = L Lᵀ of a symmetric positive definite matrix.
pub(super) struct Cholesky<'a> {
    analysis: &'a Analysis,
    /// The supernodes' panels, one after another (faer's `col_ptr_for_val` layout).
    values: Vec<f64>,
}

/// A lower triangle in compressed columns: column pointers, row indices, values.
type Lower<'a> = (&'a [usize], &'a [usize], &'a [f64]);

/// Rows and columns of the register block of [`gram`]: 8 × 4 accumulators fill eight AVX2
/// registers, leaving the rest for the loads.
const BLOCK_ROWS: usize = 8;
const BLOCK_COLS: usize = 4;

impl Analysis {
    /// Analyses the n × n symmetric matrix whose lower triangle `entries` (column, row, value)
    /// assemble; duplicates are summed. Only the pattern is read.
    pub(super) fn new(n: usize, entries: &[(usize, usize, f64)]) -> Result<Self, SolveError> {
        let (a_ptr, a_rows, a_slot) = pattern(n, || entries.iter().map(|&(col, row, _)| (col, row)));
        let a = SymbolicSparseColMatRef::new_checked(n, n, &a_ptr, None, &a_rows);
        let params = CholeskySymbolicParams {
            // faer's FORCE_SUPERNODAL (0) loses to the flop ratio 0 of a diagonal matrix; any
            // negative threshold always wins.
            supernodal_flop_ratio_threshold: SupernodalThreshold(-1.0),
            ..Default::default()
        };
        let symbolic = factorize_symbolic_cholesky(a, Side::Lower, SymmetricOrdering::Amd, params)
            .map_err(SolveError::Factorisation)?;
        let (fwd, inv) = match symbolic.perm() {
            Some(p) => {
                let (fwd, inv) = p.arrays();
                (fwd.to_vec(), inv.to_vec())
            }
            // faer leaves the ordering out when it is the identity.
            None => ((0..n).collect(), (0..n).collect()),
        };
        // A's entry (row, col) is P A Pᵀ's (inv[row], inv[col]), or its mirror in the lower
        // triangle.
        let (a_ptr, a_rows, perm) = (&a_ptr, &a_rows, &inv);
        let (col_ptr, row_idx, p_slot) = pattern(n, || {
            (0..n).flat_map(move |col| {
                a_rows[a_ptr[col]..a_ptr[col + 1]].iter().map(move |&row| {
                    let (i, j) = (perm[row], perm[col]);
                    (i.min(j), i.max(j))
                })
            })
        });
        let slot = a_slot.iter().map(|&k| p_slot[k as usize]).collect();
        Ok(Self { symbolic, fwd, inv, col_ptr, row_idx, slot })
    }

    /// Solves A x = b for the A that `entries` assemble: the pattern analysed, in the same
    /// order, with any values. They are dropped once assembled, before the factor takes its
    /// memory.
    pub(super) fn solve(
        &self,
        entries: Vec<(usize, usize, f64)>,
        mut b: Vec<f64>,
    ) -> Result<Vec<f64>, SolveError> {
        let values = self.assemble(&entries);
        drop(entries);
        self.factorise(&values)?.solve_in_place(&mut b);
        Ok(b)
    }

    /// Solves A x = b for each b of `bs`, with one factor of the A that `entries` assemble.
    pub(super) fn solve_many(
        &self,
        entries: Vec<(usize, usize, f64)>,
        mut bs: Vec<Vec<f64>>,
    ) -> Result<Vec<Vec<f64>>, SolveError> {
        let values = self.assemble(&entries);
        drop(entries);
        let factor = self.factorise(&values)?;
        for b in &mut bs {
            factor.solve_in_place(b);
        }
        Ok(bs)
    }

    /// Factorises the P A Pᵀ whose lower triangle's values [`Analysis::assemble`] gave.
    fn factorise(&self, values: &[f64]) -> Result<Cholesky<'_>, SolveError> {
        let mut factor = Cholesky { analysis: self, values: try_zeros(self.supernodal().len_val())? };
        let n = self.fwd.len();
        factor
            .factorise_on(pulp::Arch::new(), (&self.col_ptr, &self.row_idx, values))
            .map_err(|pivot| SolveError::NotPositiveDefinite { pivot, unknowns: n })?;
        Ok(factor)
    }

    /// The values of P A Pᵀ's lower triangle, each the sum of its entries in assembly order
    /// (from −0, which adds nothing to any first entry), so that it rounds the same way on
    /// every run.
    fn assemble(&self, entries: &[(usize, usize, f64)]) -> Vec<f64> {
        assert_eq!(entries.len(), self.slot.len(), "the entries of the analysed pattern");
        let mut values = vec![-0.0; self.row_idx.len()];
        for (&(col, row, value), &slot) in entries.iter().zip(&self.slot) {
            let slot = slot as usize;
            debug_assert!({
                let (i, j) = (self.inv[row], self.inv[col]);
                let lower = i.min(j);
                self.row_idx[slot] == i.max(j)
                    && (self.col_ptr[lower]..self.col_ptr[lower + 1]).contains(&slot)
            });
            values[slot] += value;
        }
        values
    }

    fn supernodal(&self) -> &SymbolicSupernodalCholesky<usize> {
        match self.symbolic.raw() {
            SymbolicCholeskyRaw::Supernodal(s) => s,
            SymbolicCholeskyRaw::Simplicial(_) => unreachable!("the analysis was asked for supernodes"),
        }
    }
}

impl Cholesky<'_> {
    /// Overwrites b with the solution x of A x = b.
    pub(super) fn solve_in_place(&self, b: &mut [f64]) {
        self.solve_in_place_on(pulp::Arch::new(), b);
    }

    fn solve_in_place_on(&self, arch: pulp::Arch, b: &mut [f64]) {
        let Analysis { fwd, inv, .. } = self.analysis;
        let mut y: Vec<f64> = fwd.iter().map(|&old| b[old]).collect();
        arch.dispatch(Substitution { symbolic: self.analysis.supernodal(), l: &self.values, y: &mut y });
        for (old, &new) in inv.iter().enumerate() {
            b[old] = y[new];
        }
    }

    /// The numeric factorisation of P A Pᵀ's lower triangle `a` into the zeroed `values`,
    /// compiled for `arch`.
    fn factorise_on(&mut self, arch: pulp::Arch, a: Lower<'_>) -> Result<(), usize> {
        arch.dispatch(Numeric { symbolic: self.analysis.supernodal(), l: &mut self.values, a })
    }
}

/// The compressed pattern of the (column, row) pairs `pairs()` yields, n columns: column
/// pointers, each column's rows (sorted, each once), and each pair's place among those rows.
///
/// A counting sort by column, then a stable sort of each column's few pairs by row (std's
/// small-slice insertion sort): near linear in the pairs, where a comparison sort of them all
/// was 8.5% of a solve. Stable, so a place's pairs are in assembly order. Pairs are counted in
/// u32, which halves the sort's memory; a mesh within any vertex budget has far fewer.
fn pattern<I>(n: usize, pairs: impl Fn() -> I) -> (Vec<usize>, Vec<usize>, Vec<u32>)
where
    I: Iterator<Item = (usize, usize)>,
{
    let mut start = vec![0usize; n + 1];
    for (col, _) in pairs() {
        start[col + 1] += 1;
    }
    for c in 0..n {
        start[c + 1] += start[c];
    }
    let len = start[n];
    assert!(u32::try_from(len).is_ok() && u32::try_from(n).is_ok(), "{len} entries in {n} columns");
    let mut next = start.clone();
    let mut by_column = vec![(0u32, 0u32); len];
    for (k, (col, row)) in pairs().enumerate() {
        by_column[next[col]] = (row as u32, k as u32);
        next[col] += 1;
    }
    let mut col_ptr = Vec::with_capacity(n + 1);
    let mut rows = Vec::with_capacity(len);
    let mut place = vec![0u32; len];
    col_ptr.push(0);
    for c in 0..n {
        let column = &mut by_column[start[c]..start[c + 1]];
        column.sort_by_key(|&(row, _)| row);
        let first = rows.len();
        for &(row, k) in &*column {
            if rows.len() == first || rows.last() != Some(&(row as usize)) {
                rows.push(row as usize);
            }
            place[k as usize] = (rows.len() - 1) as u32;
        }
        col_ptr.push(rows.len());
    }
    (col_ptr, rows, place)
}

/// A zeroed vector, or faer's out-of-memory error where the factor does not fit.
fn try_zeros(len: usize) -> Result<Vec<f64>, SolveError> {
    let mut v = Vec::new();
    v.try_reserve_exact(len).map_err(|_| SolveError::Factorisation(FaerError::OutOfMemory))?;
    v.resize(len, 0.0);
    Ok(v)
}

/// Supernode t of the factor: columns `start..start + cols`, one dense column-major panel of
/// `cols + pattern.len()` rows in `values` (its diagonal block, then its pattern's rows).
struct Node<'a> {
    start: usize,
    cols: usize,
    pattern: &'a [usize],
    values: std::ops::Range<usize>,
}

impl<'a> Node<'a> {
    fn of(s: &'a SymbolicSupernodalCholesky<usize>, t: usize) -> Self {
        let start = s.supernode_begin()[t];
        let value_ptr = s.col_ptr_for_val();
        Self {
            start,
            cols: s.supernode_end()[t] - start,
            pattern: s.supernode(t).pattern(),
            values: value_ptr[t]..value_ptr[t + 1],
        }
    }

    fn end(&self) -> usize {
        self.start + self.cols
    }

    fn rows(&self) -> usize {
        self.cols + self.pattern.len()
    }
}

/// [`numeric`] as a [`pulp::WithSimd`] operation: pulp compiles it once per instruction set
/// (every callee is `#[inline(always)]`) and runs the one this CPU has.
struct Numeric<'a> {
    symbolic: &'a SymbolicSupernodalCholesky<usize>,
    l: &'a mut [f64],
    a: Lower<'a>,
}

impl pulp::WithSimd for Numeric<'_> {
    type Output = Result<(), usize>;

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _: S) -> Self::Output {
        numeric(self.symbolic, self.l, self.a)
    }
}

/// Left-looking supernodal LLᵀ into `l` (zeroed, faer's panel layout). Returns the failing
/// pivot's (permuted) column when a pivot is not positive.
#[inline(always)]
fn numeric(s: &SymbolicSupernodalCholesky<usize>, l: &mut [f64], a: Lower<'_>) -> Result<(), usize> {
    let n = s.nrows();
    let count = s.n_supernodes();

    // Which supernode each column is in, and for each supernode the earlier ones whose
    // panels reach it (its descendants), ascending.
    let mut owner = vec![0usize; n];
    for t in 0..count {
        let node = Node::of(s, t);
        owner[node.start..node.end()].fill(t);
    }
    let mut reach_start = vec![0usize; count + 1];
    let reached_by = |visit: &mut dyn FnMut(usize, usize)| {
        for d in 0..count {
            let mut last = usize::MAX;
            for &row in s.supernode(d).pattern() {
                let t = owner[row];
                if t != last {
                    visit(t, d);
                    last = t;
                }
            }
        }
    };
    reached_by(&mut |t, _| reach_start[t + 1] += 1);
    for t in 0..count {
        reach_start[t + 1] += reach_start[t];
    }
    let mut next = reach_start.clone();
    let mut descendants = vec![0usize; reach_start[count]];
    reached_by(&mut |t, d| {
        descendants[next[t]] = d;
        next[t] += 1;
    });

    // Row of the current panel that each global row maps to.
    let mut local = vec![usize::MAX; n];
    let mut product = Vec::new();
    let (col_ptr, row_idx, values) = a;
    for t in 0..count {
        let node = Node::of(s, t);
        let (start, end, cols, rows) = (node.start, node.end(), node.cols, node.rows());
        for (i, &row) in node.pattern.iter().enumerate() {
            local[row] = cols + i;
        }
        let (done, rest) = l.split_at_mut(node.values.start);
        let panel = &mut rest[..node.values.len()];
        let to_local = |row: usize| if row < end { row - start } else { local[row] };

        for j in start..end {
            for k in col_ptr[j]..col_ptr[j + 1] {
                panel[(j - start) * rows + to_local(row_idx[k])] += values[k];
            }
        }

        for &d in &descendants[reach_start[t]..reach_start[t + 1]] {
            let d = Node::of(s, d);
            let d_panel = &done[d.values.clone()];
            let first = d.pattern.partition_point(|&r| r < start);
            let inside = d.pattern[first..].partition_point(|&r| r < end);
            let below = &d.pattern[first..];
            let m = below.len();
            // Every entry that the scatter reads, gram writes: no need to clear.
            if product.len() < m * inside {
                product.resize(m * inside, 0.0);
            }
            gram(d_panel, d.rows(), d.cols + first, m, inside, d.cols, &mut product);
            for (jj, &col) in below[..inside].iter().enumerate() {
                let target = &mut panel[(col - start) * rows..][..rows];
                for (i, &row) in below.iter().enumerate().skip(jj) {
                    target[to_local(row)] -= product[jj * m + i];
                }
            }
        }

        factor_panel(panel, rows, cols, &mut product).map_err(|j| start + j)?;
        for &row in node.pattern {
            local[row] = usize::MAX;
        }
    }
    Ok(())
}

/// Dense LLᵀ of a panel's diagonal block and the solve of the rows below it, in place, by
/// blocks of [`BLOCK_COLS`] columns: the block first takes the product of every earlier
/// column ([`gram`]), then is finished column by column. Returns the failing column.
#[inline(always)]
fn factor_panel(panel: &mut [f64], rows: usize, cols: usize, scratch: &mut Vec<f64>) -> Result<(), usize> {
    for j0 in (0..cols).step_by(BLOCK_COLS) {
        let width = BLOCK_COLS.min(cols - j0);
        let m = rows - j0;
        if j0 > 0 {
            if scratch.len() < m * width {
                scratch.resize(m * width, 0.0);
            }
            gram(panel, rows, j0, m, width, j0, scratch);
            for c in 0..width {
                let column = &mut panel[(j0 + c) * rows + j0..][..m];
                for (x, &p) in column.iter_mut().zip(&scratch[c * m..][..m]).skip(c) {
                    *x -= p;
                }
            }
        }
        for j in j0..j0 + width {
            let (left, right) = panel.split_at_mut(j * rows);
            let column = &mut right[..rows];
            for k in j0..j {
                let earlier = &left[k * rows..][..rows];
                let factor = -earlier[j];
                for (x, &e) in column[j..].iter_mut().zip(&earlier[j..]) {
                    *x = e.mul_add(factor, *x);
                }
            }
            let pivot = column[j];
            if !(pivot > 0.0 && pivot.is_finite()) {
                return Err(j);
            }
            let diagonal = pivot.sqrt();
            column[j] = diagonal;
            for x in &mut column[j + 1..] {
                *x /= diagonal;
            }
        }
    }
    Ok(())
}

/// out[jj·m + i] = Σ_{k < depth} P[first + i, k] · P[first + jj, k] for jj < width and
/// jj ≤ i < m, P being the column-major panel with `rows` rows; some entries above the
/// diagonal are written too, and are not read. Each entry is one `mul_add` chain over k in
/// increasing order, whichever block computes it.
#[inline(always)]
fn gram(p: &[f64], rows: usize, first: usize, m: usize, width: usize, depth: usize, out: &mut [f64]) {
    let panel = Panel { p, rows, first, m, depth };
    for j0 in (0..width).step_by(BLOCK_COLS) {
        match width - j0 {
            1 => panel.columns::<1>(j0, out),
            2 => panel.columns::<2>(j0, out),
            3 => panel.columns::<3>(j0, out),
            _ => panel.columns::<BLOCK_COLS>(j0, out),
        }
    }
}

/// The arguments of [`gram`].
struct Panel<'a> {
    p: &'a [f64],
    rows: usize,
    first: usize,
    m: usize,
    depth: usize,
}

impl Panel<'_> {
    /// [`gram`]'s columns j0..j0 + C, rows j0..m: [`BLOCK_ROWS`] rows at a time in registers,
    /// then the rows left over one at a time.
    #[inline(always)]
    fn columns<const C: usize>(&self, j0: usize, out: &mut [f64]) {
        let Self { p, rows, first, m, depth } = *self;
        let mut i0 = j0;
        while i0 + BLOCK_ROWS <= m {
            let mut acc = [[0.0f64; BLOCK_ROWS]; C];
            for k in 0..depth {
                let column = &p[k * rows + first..];
                let x: &[f64; BLOCK_ROWS] = column[i0..i0 + BLOCK_ROWS].try_into().expect("a full block");
                for (c, acc) in acc.iter_mut().enumerate() {
                    let y = column[j0 + c];
                    for (a, &x) in acc.iter_mut().zip(x) {
                        *a = x.mul_add(y, *a);
                    }
                }
            }
            for (c, acc) in acc.iter().enumerate() {
                out[(j0 + c) * m + i0..][..BLOCK_ROWS].copy_from_slice(acc);
            }
            i0 += BLOCK_ROWS;
        }
        for i in i0..m {
            let mut acc = [0.0f64; C];
            for k in 0..depth {
                let column = &p[k * rows + first..];
                let x = column[i];
                for (c, a) in acc.iter_mut().enumerate() {
                    *a = x.mul_add(column[j0 + c], *a);
                }
            }
            for (c, &a) in acc.iter().enumerate() {
                out[(j0 + c) * m + i] = a;
            }
        }
    }
}

/// [`forward`] then [`backward`] as a [`pulp::WithSimd`] operation, as [`Numeric`] is: each
/// `mul_add` is then one instruction where the CPU has FMA, not a call into libm's `fma`
/// (the same bits: both round once).
struct Substitution<'a> {
    symbolic: &'a SymbolicSupernodalCholesky<usize>,
    l: &'a [f64],
    y: &'a mut [f64],
}

impl pulp::WithSimd for Substitution<'_> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _: S) {
        forward(self.symbolic, self.l, self.y);
        backward(self.symbolic, self.l, self.y);
    }
}

/// L y = b in place.
#[inline(always)]
fn forward(s: &SymbolicSupernodalCholesky<usize>, l: &[f64], y: &mut [f64]) {
    for t in 0..s.n_supernodes() {
        let node = Node::of(s, t);
        let (start, cols, pattern, rows) = (node.start, node.cols, node.pattern, node.rows());
        let panel = &l[node.values];
        for jj in 0..cols {
            let column = &panel[jj * rows..][..rows];
            let x = y[start + jj] / column[jj];
            y[start + jj] = x;
            for i in jj + 1..cols {
                y[start + i] = column[i].mul_add(-x, y[start + i]);
            }
            for (&row, &v) in pattern.iter().zip(&column[cols..]) {
                y[row] = v.mul_add(-x, y[row]);
            }
        }
    }
}

/// Lᵀ x = y in place.
#[inline(always)]
fn backward(s: &SymbolicSupernodalCholesky<usize>, l: &[f64], y: &mut [f64]) {
    for t in (0..s.n_supernodes()).rev() {
        let node = Node::of(s, t);
        let (start, cols, pattern, rows) = (node.start, node.cols, node.pattern, node.rows());
        let panel = &l[node.values];
        for jj in (0..cols).rev() {
            let column = &panel[jj * rows..][..rows];
            let mut sum = y[start + jj];
            for (&row, &v) in pattern.iter().zip(&column[cols..]) {
                sum = v.mul_add(-y[row], sum);
            }
            for i in jj + 1..cols {
                sum = column[i].mul_add(-y[start + i], sum);
            }
            y[start + jj] = sum / column[jj];
        }
    }
}

#[cfg(test)]
mod tests;
