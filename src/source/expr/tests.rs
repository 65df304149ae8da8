//! Tests of expressions: parsing, errors with their columns, and the evaluators' agreement.

use super::program::{Op, compile, fuse, max_of, min_of};
use super::*;
use crate::geom::Point;
use crate::source::Surface;
use meval::shunting_yard::to_rpn;
use meval::tokenizer::tokenize;
use proptest::prelude::*;

fn column(text: &str) -> usize {
    Expression::parse(text).unwrap_err().column
}

/// The fuzzer's crash of 2026-12-05 (`fuzz/run.sh`, target `expression`): the closures
/// and the batched program disagreed on the sign of a zero from `max`.
#[test]
fn max_and_min_give_the_same_signed_zero_on_every_path() {
    let cases = [
        "max( y,x, y,0-x) % 0.5",
        "min(x, y) % 0.5",
        "max(0-x, x) % 0.5",
        "min(0-y, y, x) % 0.5",
        "max(x) + min(y)",
    ];
    let points = [Point::new(0.0, -0.0), Point::new(-0.0, 0.0), Point::new(-0.0, -0.0), Point::new(0.0, 0.0)];
    for text in cases {
        let f = Expression::parse(text).unwrap();
        // More points than a batch takes one by one, so the batched program runs too.
        let many: Vec<Point> = points.iter().copied().cycle().take(4 * points.len()).collect();
        // In both builds of the batch evaluator (one build twice on a CPU without AVX2).
        for arch in [pulp::Arch::Scalar, pulp::Arch::new()] {
            let mut out = vec![0.0; many.len()];
            f.eval_many_on(arch, &many, &mut out);
            for (p, got) in many.iter().zip(&out) {
                let (closures, program) = (f.eval_xy(p.x, p.y), f.run_program(p.x, p.y));
                assert_eq!(closures.to_bits(), program.to_bits(), "{text} at {p:?}");
                assert_eq!(closures.to_bits(), got.to_bits(), "{text} at {p:?}: batched");
            }
        }
    }
    // And the rule itself: of equal values the first, and a NaN gives way. (Which zero
    // `f64::max` gives depends on the build: in this one the paths above may agree even
    // with it, so this is what fails if it comes back.)
    assert_eq!(max_of(-0.0, 0.0).to_bits(), (-0.0f64).to_bits());
    assert_eq!(min_of(0.0, -0.0).to_bits(), 0.0f64.to_bits());
    assert_eq!((max_of(f64::NAN, 1.0), max_of(1.0, f64::NAN), min_of(f64::NAN, 2.0)), (1.0, 1.0, 2.0));
}

#[test]
fn errors_carry_the_column_of_the_offending_token() {
    assert_eq!(column("x + z"), 5);
    assert_eq!(column("sin(x) * foo(y)"), 10);
    assert_eq!(column("x $ y"), 3);
    assert_eq!(column("atan2(x) + 1"), 1);
    // meval's tokenizer stops at the `)` of an empty call.
    assert_eq!(column("1 + atan2(x, y) + max()"), 23);
    assert_eq!(column("(x + y"), 7);
    assert_eq!(column("x +"), 4);
    assert_eq!(column("   "), 1);
    // Columns count characters, not bytes.
    assert_eq!(column("é"), 1);
    assert_eq!(column("x + ß"), 5);
}

#[test]
fn error_messages_say_what_to_fix() {
    let e = Expression::parse("x * t").unwrap_err();
    assert_eq!(e.to_string(), "unknown variable `t` (use x and y) at column 5");
    let e = Expression::parse("sin(x, y)").unwrap_err();
    assert_eq!(e.kind.to_string(), "function `sin` takes 1 argument(s), got 2");
    let e = Expression::parse("((x)").unwrap_err();
    assert_eq!(e.kind, ExprErrorKind::MissingClosingParens(1));
}

#[test]
fn deep_nesting_is_refused_instead_of_overflowing() {
    let deep = format!("{}x{}", "(x + ".repeat(100), ")".repeat(100));
    assert_eq!(Expression::parse(&deep).unwrap_err().kind, ExprErrorKind::TooDeep);
    let fine = format!("{}x{}", "(x + ".repeat(40), ")".repeat(40));
    assert_eq!(Expression::parse(&fine).unwrap().eval_xy(1.0, 0.0), 41.0);
}

#[test]
fn operators_follow_mevals_precedence() {
    let f = |s: &str| Expression::parse(s).unwrap().eval_xy(2.0, 3.0);
    assert_eq!(f("-x^2"), -4.0);
    assert_eq!(f("(x + 0.5)^2"), 6.25);
    assert_eq!(f("2^2^y"), 256.0);
    assert_eq!(f("x^y^2"), 512.0);
    assert_eq!(f("x - y - 1"), -2.0);
    assert_eq!(f("7 % y"), 1.0);
    assert_eq!(f("max(x, y, 1) + min(x, y)"), 5.0);
    assert_eq!(f("atan2(0, -1) - pi"), 0.0);
    assert_eq!(f("+x"), 2.0);
    assert_eq!(f("1.5e1 + 2E-1"), 15.2);
}

#[test]
fn a_chain_too_tall_for_closures_runs_on_the_stack_program_with_the_same_bits() {
    // `x+x+…` nests to the left: stack depth 2, tree height 4,000.
    let long = vec!["x"; 4000].join("+");
    let f = Expression::parse(&long).unwrap();
    assert!(f.scalar.is_none(), "a 4,000-level tree was built as closures");
    assert_eq!(f.eval_xy(0.25, 0.0), 1000.0);
    let short = Expression::parse(&vec!["x"; 100].join("+")).unwrap();
    assert!(short.scalar.is_some());
    assert_eq!(short.eval_xy(0.1, 0.0).to_bits(), short.run_program(0.1, 0.0).to_bits());
}

fn expression() -> impl Strategy<Value = String> {
    let leaf = prop_oneof![
        Just("x".to_owned()),
        Just("y".to_owned()),
        Just("pi".to_owned()),
        (0u32..100).prop_map(|n| format!("{}.{}", n / 10, n % 10)),
    ];
    leaf.prop_recursive(4, 24, 3, |inner| {
        prop_oneof![
            (inner.clone(), inner.clone(), "[-+*/^%]").prop_map(|(a, b, op)| format!("({a}) {op} {b}")),
            (inner.clone(), "sin|cos|exp|abs|tanh|sqrt|atan").prop_map(|(a, f)| format!("{f}({a})")),
            (inner.clone(), inner.clone(), "max|min|atan2").prop_map(|(a, b, f)| format!("{f}({a}, {b})")),
            (inner.clone(), inner.clone(), inner.clone()).prop_map(|(a, b, c)| format!("min({a}, {b}, {c})")),
            inner.clone().prop_map(|a| format!("-{a}")),
        ]
    })
}

/// `text` compiled without [`fuse`] and with it, both run by the stack program.
fn unfused_and_fused(text: &str) -> [Expression; 2] {
    let rpn = to_rpn(&tokenize(text).unwrap()).unwrap();
    let unfused = compile(&rpn).unwrap();
    [unfused.clone(), fuse(unfused)].map(|program| Expression {
        text: text.to_owned(),
        program,
        scalar: None,
    })
}

#[test]
fn franke_loses_its_constants_to_fusing() {
    let franke = "0.75*exp(-((9*x-2)^2 + (9*y-2)^2)/4) + 0.75*exp(-((9*x+1)^2)/49 - (9*y+1)/10) \
                  + 0.5*exp(-((9*x-7)^2 + (9*y-3)^2)/4) - 0.2*exp(-((9*x-4)^2) - (9*y-7)^2)";
    let [unfused, fused] = unfused_and_fused(franke);
    let consts = |e: &Expression| e.program.iter().filter(|op| matches!(op, Op::Const(_))).count();
    assert_eq!((unfused.program.len(), consts(&unfused)), (78, 24));
    assert_eq!((fused.program.len(), consts(&fused)), (54, 0));
    let p = Point::new(0.3, 0.7);
    assert_eq!(unfused.eval(p).to_bits(), fused.eval(p).to_bits());
}

proptest! {
    #[test]
    fn fused_programs_give_the_unfused_bits(
        text in expression(),
        points in prop::collection::vec((-3.0..3.0f64, -3.0..3.0f64), 1..40),
    ) {
        let [unfused, fused] = unfused_and_fused(&text);
        let points: Vec<Point> = points.into_iter().map(|(x, y)| Point::new(x, y)).collect();
        let mut batches = [vec![0.0; points.len()], vec![0.0; points.len()]];
        for (e, out) in [&unfused, &fused].into_iter().zip(&mut batches) {
            e.eval_many(&points, out);
        }
        for (i, p) in points.iter().enumerate() {
            let (a, b) = (unfused.eval(*p), fused.eval(*p));
            prop_assert!(a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()), "{text} at {p:?}: {a} vs {b}");
            let (a, b) = (batches[0][i], batches[1][i]);
            prop_assert!(a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()), "{text} batched at {p:?}: {a} vs {b}");
        }
    }

    #[test]
    fn compiled_program_agrees_with_meval(text in expression(), x in -3.0..3.0f64, y in -3.0..3.0f64) {
        let ours = Expression::parse(&text).unwrap().eval_xy(x, y);
        let theirs = text.parse::<meval::Expr>().unwrap().bind2("x", "y").unwrap()(x, y);
        // libm and the platform's libm may differ in the last bits.
        let close = ours == theirs
            || (ours.is_nan() && theirs.is_nan())
            || (ours - theirs).abs() <= 1e-9 * theirs.abs().max(1.0);
        prop_assert!(close, "{text} at ({x}, {y}): ours {ours}, meval {theirs}");
    }

    #[test]
    fn batches_give_the_same_bits_as_single_points(
        text in expression(),
        points in prop::collection::vec((-3.0..3.0f64, -3.0..3.0f64), 0..40),
    ) {
        let f = Expression::parse(&text).unwrap();
        let points: Vec<Point> = points.into_iter().map(|(x, y)| Point::new(x, y)).collect();
        let mut out = vec![0.0; points.len()];
        f.eval_many(&points, &mut out);
        for (p, &got) in points.iter().zip(&out) {
            let want = f.eval_xy(p.x, p.y);
            prop_assert!(got.to_bits() == want.to_bits() || (got.is_nan() && want.is_nan()), "{text} at {p:?}: {got} vs {want}");
        }
    }

    /// The batch evaluator compiled for AVX2 and for the x86-64 baseline, on the same
    /// points (several batches and a short last one, with `exp` of any size), agree bit
    /// for bit. Skipped where the CPU has no AVX2, as the two would be one build.
    #[test]
    fn the_avx2_build_gives_the_portable_bits(
        text in expression(),
        points in prop::collection::vec((-800.0..800.0f64, -3.0..3.0f64), 6..80),
    ) {
        let arch = pulp::Arch::new();
        if matches!(arch, pulp::Arch::Scalar) {
            return Ok(());
        }
        let f = Expression::parse(&format!("({text}) + exp(x) * exp(y * {text})")).unwrap();
        let points: Vec<Point> = points.into_iter().map(|(x, y)| Point::new(x, y)).collect();
        let mut outs = [vec![0.0; points.len()], vec![0.0; points.len()]];
        for (arch, out) in [pulp::Arch::Scalar, arch].into_iter().zip(&mut outs) {
            f.eval_many_on(arch, &points, out);
        }
        // A NaN's sign and payload are not promised by Rust, and F is never NaN in an output.
        for (i, p) in points.iter().enumerate() {
            let (a, b) = (outs[0][i], outs[1][i]);
            prop_assert!(a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()), "{} at {:?}: {a} vs {b}", f.text(), p);
        }
    }

    #[test]
    fn arbitrary_text_never_panics_and_errors_point_inside_the_text(text in "[ xy0-9a-z()+*/^,.$-]{0,30}") {
        if let Err(e) = Expression::parse(&text) {
            prop_assert!(e.column >= 1 && e.column <= text.chars().count() + 1, "{text}: {e}");
        }
    }
}
