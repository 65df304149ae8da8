//! `libm`'s `exp` over a batch's lanes, bit for bit.
//!
//! `libm::exp` (FreeBSD's `e_exp.c`) branches on the size of its argument, divides, and ends
//! in `scalbn`. One lane at a time, that call was most of a batch of Franke's function
//! (docs/speed.md). Here four lanes run together: the branches that pick the reduction are
//! selects, so the compiler keeps the lanes in vector registers (one AVX2 register, or two on
//! the x86-64 baseline: this is inlined into the batch evaluator, which is compiled for
//! both) and the divisions overlap. A lane outside the common range (|x| ≥ 708.39,
//! |x| ≤ 2⁻²⁸, NaN) is left to `libm::exp` itself. On every other lane the operations, and
//! their order, are libm's, so the results are the same bits on every machine and with
//! either instruction set.

// libm's constants, by the bit patterns its source gives them.
const LN2HI: f64 = f64::from_bits(0x3fe6_2e42_fee0_0000);
const LN2LO: f64 = f64::from_bits(0x3dea_39ef_3579_3c76);
const INVLN2: f64 = f64::from_bits(0x3ff7_1547_652b_82fe);
const P1: f64 = f64::from_bits(0x3fc5_5555_5555_553e);
const P2: f64 = f64::from_bits(0xbf66_c16c_16be_bd93);
const P3: f64 = f64::from_bits(0x3f11_566a_af25_de2c);
const P4: f64 = f64::from_bits(0xbebb_bd41_c5d2_6bf1);
const P5: f64 = f64::from_bits(0x3e66_3769_72be_a4d0);

/// Lanes computed together.
const WIDTH: usize = 4;

/// Each value of `lanes` replaced by `libm::exp` of it. Inlined, so that it is compiled for
/// the instruction set of the batch evaluator that calls it.
#[inline(always)]
pub(super) fn exp(lanes: &mut [f64]) {
    let mut chunks = lanes.chunks_exact_mut(WIDTH);
    for chunk in &mut chunks {
        exp_chunk(chunk);
    }
    // Two or three last lanes as a chunk of their own, padded with a common-range argument;
    // a single one costs less through libm (`benches/expression.rs`, batches of 9 and 6).
    let rest = chunks.into_remainder();
    if let [v] = rest {
        *v = libm::exp(*v);
    } else if !rest.is_empty() {
        let mut padded = [1.0; WIDTH];
        padded[..rest.len()].copy_from_slice(rest);
        exp_chunk(&mut padded);
        rest.copy_from_slice(&padded[..rest.len()]);
    }
}

/// [`exp`] of one chunk of [`WIDTH`] lanes.
#[inline(always)]
fn exp_chunk(chunk: &mut [f64]) {
    let x: [f64; WIDTH] = (*chunk).try_into().expect("chunks of WIDTH");
    let (y, rare) = exp_common(x);
    chunk.copy_from_slice(&y);
    if rare {
        for (out, x) in chunk.iter_mut().zip(x) {
            if is_rare(high_word(x)) {
                *out = libm::exp(x);
            }
        }
    }
}

/// The high 32 bits of |x|, which libm's branches test.
#[inline(always)]
fn high_word(x: f64) -> u32 {
    (x.to_bits() >> 32) as u32 & 0x7fff_ffff
}

/// Whether libm takes a path of its own for the argument with high word `hx`: overflow,
/// underflow and NaN from |x| ≥ 708.39, or 1 + x for |x| ≤ 2⁻²⁸.
#[inline(always)]
fn is_rare(hx: u32) -> bool {
    hx >= 0x4086_232b || hx <= 0x3e30_0000
}

/// libm's exp on each lane as if its argument were in the common range, and whether any
/// lane is not.
#[inline(always)]
fn exp_common(x: [f64; WIDTH]) -> ([f64; WIDTH], bool) {
    let mut y = [0.0; WIDTH];
    let mut rare = false;
    for (out, x) in y.iter_mut().zip(x) {
        let hx = high_word(x);
        rare |= is_rare(hx);
        // Argument reduction, x = k ln2 + r: k rounded from x / ln2 when |x| ≥ 1.5 ln2, ±1
        // when |x| > 0.5 ln2, else 0 (where libm skips the reduction, which with k = 0 gives
        // the same hi = x, lo = 0 and r = x). All three are computed and one is selected, so
        // that no lane branches.
        let rounded = (INVLN2 * x + 0.5f64.copysign(x)) as i32;
        let unit = if x.is_sign_negative() { -1 } else { 1 };
        let k = if hx >= 0x3ff0_a2b2 {
            rounded
        } else if hx > 0x3fd6_2e42 {
            unit
        } else {
            0
        };
        let kf = f64::from(k);
        let hi = x - kf * LN2HI;
        let lo = kf * LN2LO;
        let r = hi - lo;
        // exp(r) by the rational approximation.
        let rr = r * r;
        let c = r - rr * (P1 + rr * (P2 + rr * (P3 + rr * (P4 + rr * P5))));
        let e = 1.0 + (r * c / (2.0 - c) - lo + hi);
        // scalbn(e, k): in the common range |k| ≤ 1022, so 2^k is a normal number and
        // scalbn is this one product (and e · 1 = e where libm returns e for k = 0).
        // (A rare lane's k may be anything; its result is replaced.)
        *out = e * f64::from_bits((0x3ff_i32.wrapping_add(k) as u64) << 52);
    }
    (y, rare)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// [`exp`] compiled for whichever instruction set pulp dispatches to, as the batch
    /// evaluator compiles it.
    struct Exp<'a>(&'a mut [f64]);

    impl pulp::WithSimd for Exp<'_> {
        type Output = ();

        #[inline(always)]
        fn with_simd<S: pulp::Simd>(self, _: S) {
            exp(self.0);
        }
    }

    /// `exp` against `libm::exp` on `values`, with every lane position and remainder length,
    /// in the x86-64 baseline build and in the one this CPU runs (AVX2 where it has it).
    fn check(values: &[f64]) -> Result<(), TestCaseError> {
        for arch in [pulp::Arch::Scalar, pulp::Arch::new()] {
            check_on(arch, values)?;
        }
        Ok(())
    }

    fn check_on(arch: pulp::Arch, values: &[f64]) -> Result<(), TestCaseError> {
        let mut lanes = values.to_vec();
        arch.dispatch(Exp(&mut lanes));
        for (x, got) in values.iter().zip(&lanes) {
            let want = libm::exp(*x);
            prop_assert_eq!(
                got.to_bits(),
                want.to_bits(),
                "exp({:e} = {:#x}): {:e}, libm {:e}",
                x,
                x.to_bits(),
                got,
                want
            );
        }
        Ok(())
    }

    /// The edges of libm's branches and of the common range, with their neighbours.
    fn boundaries() -> Vec<f64> {
        let edges = [
            0x4086_232b_u32, // |x| ≥ 708.39: overflow, underflow
            0x3ff0_a2b2,     // |x| ≥ 1.5 ln2: k rounded from x / ln2
            0x3fd6_2e42,     // |x| > 0.5 ln2: k = ±1
            0x3e30_0000,     // |x| > 2^-28: the polynomial
        ];
        let mut out = Vec::new();
        for hx in edges {
            for high in [hx - 1, hx, hx + 1] {
                for low in [0, 1, 0x8000_0000, u32::MAX] {
                    let bits = (u64::from(high) << 32) | u64::from(low);
                    out.extend([f64::from_bits(bits), -f64::from_bits(bits)]);
                }
            }
        }
        out.extend([
            0.0,
            -0.0,
            1.0,
            -1.0,
            709.782712893384,
            709.79,
            -745.1332191019411,
            -745.14,
            -708.4,
            f64::MIN_POSITIVE,
            f64::MAX,
            f64::MIN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
        ]);
        out
    }

    #[test]
    fn every_branch_boundary_gives_libms_bits() {
        let values = boundaries();
        // Each value in every lane position of a chunk, and in the remainder.
        for shift in 0..WIDTH {
            let mut shifted = vec![0.5; shift];
            shifted.extend(&values);
            check(&shifted).unwrap();
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2_000))]

        /// Where Franke's and most users' arguments are, densely.
        #[test]
        fn arguments_of_everyday_size_give_libms_bits(values in prop::collection::vec(-40.0..40.0f64, 0..37)) {
            check(&values)?;
        }

        /// Every magnitude, the special ones included.
        #[test]
        fn any_bit_pattern_gives_libms_bits(bits in prop::collection::vec(any::<u64>(), 0..37)) {
            let values: Vec<f64> = bits.into_iter().map(f64::from_bits).collect();
            check(&values)?;
        }

        /// The whole range of the common path, which the reduction's k spans, and a little past
        /// both ends, where exp overflows and underflows.
        #[test]
        fn the_whole_finite_range_gives_libms_bits(values in prop::collection::vec(-746.0..710.0f64, 0..37)) {
            check(&values)?;
        }
    }
}
