//! [`Expression`]: a parsed F(x, y), evaluated one point at a time through its closures or in
//! batches through its stack program.

use super::error::{ExprError, ExprErrorKind, MAX_DEPTH, column_of, token_starts};
use super::program::{Lanes, Op, check_names, compile, fuse, max_of, min_of};
use super::{closures, hint, lanes};
use crate::geom::Point;
use crate::source::Surface;
use meval::shunting_yard::{RPNError, to_rpn};
use meval::tokenizer::{ParseError, tokenize};
use std::cell::RefCell;
use std::fmt;
use std::sync::{Arc, LazyLock};

/// A parsed expression F(x, y).
///
/// ```
/// use meshfit::geom::Point;
/// use meshfit::source::{Expression, Surface};
/// let f = Expression::parse("sin(x) * cos(y) + x^2").unwrap();
/// assert_eq!(f.eval(Point::new(0.0, 1.0)), 0.0);
/// let err = Expression::parse("x + z").unwrap_err();
/// assert_eq!(err.column, 5);
/// ```
#[derive(Clone)]
pub struct Expression {
    pub(super) text: String,
    pub(super) program: Vec<Op>,
    /// The program as closures, for one point at a time (absent for a very tall tree).
    pub(super) scalar: Option<Arc<dyn Fn(f64, f64) -> f64 + Send + Sync>>,
}

impl fmt::Debug for Expression {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_tuple("Expression").field(&self.text).finish()
    }
}

impl Expression {
    /// Parses `text` with meval's grammar and builtins, allowing the variables x and y.
    ///
    /// # Errors
    /// A syntax error, an unknown name or a wrong number of arguments, with its column.
    pub fn parse(text: &str) -> Result<Self, ExprError> {
        Self::parse_unhinted(text).map_err(|mut e| {
            e.hint = hint::hint(text, &e);
            e
        })
    }

    fn parse_unhinted(text: &str) -> Result<Self, ExprError> {
        let at_end = text.chars().count() + 1;
        if text.trim().is_empty() {
            return Err(ExprError { column: 1, kind: ExprErrorKind::Empty, hint: None });
        }
        let tokens = tokenize(text).map_err(|e| match e {
            ParseError::UnexpectedToken(byte) => {
                let column = column_of(text, byte);
                let found = text[byte..].chars().next().map_or_else(String::new, String::from);
                ExprError { column, kind: ExprErrorKind::UnexpectedToken(found), hint: None }
            }
            ParseError::MissingRParen(n) => ExprError {
                column: at_end,
                kind: ExprErrorKind::MissingClosingParens(n.max(1) as usize),
                hint: None,
            },
            ParseError::MissingArgument => {
                ExprError { column: at_end, kind: ExprErrorKind::MissingOperand, hint: None }
            }
        })?;
        let starts = token_starts(text);
        // Our scanner mirrors meval's; should they ever disagree, point at the start.
        let column = |index: usize| {
            if starts.len() == tokens.len() {
                starts.get(index).map_or(at_end, |&b| column_of(text, b))
            } else {
                1
            }
        };
        check_names(&tokens).map_err(|(index, kind)| ExprError {
            column: column(index),
            kind,
            hint: None,
        })?;
        let rpn = to_rpn(&tokens).map_err(|e| {
            let (index, what) = match e {
                RPNError::MismatchedLParen(i) => (i, "unmatched `(`"),
                RPNError::MismatchedRParen(i) => (i, "unmatched `)`"),
                RPNError::UnexpectedComma(i) => (i, "comma outside a function call"),
                RPNError::NotEnoughOperands(i) => (i, "operator without an operand"),
                RPNError::TooManyOperands => (0, "operands without an operator"),
            };
            ExprError { column: column(index), kind: ExprErrorKind::Unbalanced(what), hint: None }
        })?;
        let program = fuse(compile(&rpn).map_err(|kind| ExprError { column: 1, kind, hint: None })?);
        let scalar = closures::build(&program).map(Arc::from);
        Ok(Self { text: text.to_owned(), program, scalar })
    }

    /// The text it was parsed from.
    pub fn text(&self) -> &str {
        &self.text
    }

    /// F(x, y).
    #[inline]
    pub fn eval_xy(&self, x: f64, y: f64) -> f64 {
        match &self.scalar {
            Some(f) => f(x, y),
            None => self.run_program(x, y),
        }
    }

    /// F(x, y) by the stack program: the same bits as the closures, several times slower.
    pub(super) fn run_program(&self, x: f64, y: f64) -> f64 {
        let mut stack = [0.0f64; MAX_DEPTH];
        let mut sp = 0usize;
        // `compile` verified the depth and operand counts, so the indexing below stays in
        // bounds; the checks the compiler still emits are cheap next to the arithmetic.
        for op in &self.program {
            match *op {
                Op::Const(c) => {
                    stack[sp] = c;
                    sp += 1;
                }
                Op::X => {
                    stack[sp] = x;
                    sp += 1;
                }
                Op::Y => {
                    stack[sp] = y;
                    sp += 1;
                }
                Op::Neg => stack[sp - 1] = -stack[sp - 1],
                Op::Square => stack[sp - 1] *= stack[sp - 1],
                Op::Call(f, _) => stack[sp - 1] = f(stack[sp - 1]),
                Op::AddConst(c) => stack[sp - 1] += c,
                Op::SubConst(c) => stack[sp - 1] -= c,
                Op::MulConst(c) => stack[sp - 1] *= c,
                Op::DivConst(c) => stack[sp - 1] /= c,
                Op::ConstSub(c) => stack[sp - 1] = c - stack[sp - 1],
                Op::ConstDiv(c) => stack[sp - 1] = c / stack[sp - 1],
                Op::Add | Op::Sub | Op::Mul | Op::Div | Op::Rem | Op::Pow | Op::Atan2 => {
                    sp -= 1;
                    let (l, r) = (stack[sp - 1], stack[sp]);
                    stack[sp - 1] = match *op {
                        Op::Add => l + r,
                        Op::Sub => l - r,
                        Op::Mul => l * r,
                        Op::Div => l / r,
                        Op::Rem => l % r,
                        Op::Pow => libm::pow(l, r),
                        _ => libm::atan2(l, r),
                    };
                }
                Op::Max(n) | Op::Min(n) => {
                    let n = n as usize;
                    let args = &stack[sp - n..sp];
                    let v = if matches!(*op, Op::Max(_)) {
                        args.iter().fold(f64::NEG_INFINITY, |m, &a| max_of(m, a))
                    } else {
                        args.iter().fold(f64::INFINITY, |m, &a| min_of(m, a))
                    };
                    sp -= n;
                    stack[sp] = v;
                    sp += 1;
                }
            }
        }
        stack[0]
    }
}

/// Points evaluated together by [`Expression::eval_many`]: each operation is decoded once per
/// batch and runs over all lanes in a tight loop. 32 holds a step's samples in the error
/// criterion (about 30) in one batch; the lanes' stack is then 16 KiB, within L1.
pub const BATCH: usize = 32;

/// Batches smaller than this run one point at a time through the closures.
pub(super) const SCALAR_BELOW: usize = 6;

thread_local! {
    /// The lanes of the batch evaluator's stack, kept per thread so a batch neither allocates
    /// nor clears 16 KiB of stack each time.
    static LANES: RefCell<Vec<[f64; BATCH]>> = const { RefCell::new(Vec::new()) };
}

impl Expression {
    /// F at each of `points` into `out` (same length), bit for bit what
    /// [`Expression::eval_xy`] gives: the same operations in the same order on each lane.
    ///
    /// The batch evaluator is compiled twice, for AVX2 and for the x86-64 baseline, and runs
    /// the one this CPU has; the bits are the same (IEEE operations round alike at any width,
    /// and Rust never fuses a product and a sum).
    pub fn eval_many(&self, points: &[Point], out: &mut [f64]) {
        static ARCH: LazyLock<pulp::Arch> = LazyLock::new(pulp::Arch::new);
        self.eval_many_on(*ARCH, points, out);
    }

    pub(super) fn eval_many_on(&self, arch: pulp::Arch, points: &[Point], out: &mut [f64]) {
        assert_eq!(points.len(), out.len(), "one output per point");
        LANES.with_borrow_mut(|stack| {
            if stack.len() < MAX_DEPTH {
                stack.resize(MAX_DEPTH, [0.0; BATCH]);
            }
            arch.dispatch(Batches { f: self, points, out, stack });
        });
    }

    #[inline(always)]
    fn eval_batch(&self, points: &[Point], out: &mut [f64], stack: &mut [[f64; BATCH]]) {
        let n = points.len();
        let mut sp = 0usize;
        for op in &self.program {
            match *op {
                Op::Const(c) => {
                    stack[sp][..n].fill(c);
                    sp += 1;
                }
                Op::X | Op::Y => {
                    let lane = &mut stack[sp][..n];
                    for (v, p) in lane.iter_mut().zip(points) {
                        *v = if matches!(op, Op::X) { p.x } else { p.y };
                    }
                    sp += 1;
                }
                Op::Neg => stack[sp - 1][..n].iter_mut().for_each(|v| *v = -*v),
                Op::Square => stack[sp - 1][..n].iter_mut().for_each(|v| *v *= *v),
                Op::AddConst(c) => stack[sp - 1][..n].iter_mut().for_each(|v| *v += c),
                Op::SubConst(c) => stack[sp - 1][..n].iter_mut().for_each(|v| *v -= c),
                Op::MulConst(c) => stack[sp - 1][..n].iter_mut().for_each(|v| *v *= c),
                Op::DivConst(c) => stack[sp - 1][..n].iter_mut().for_each(|v| *v /= c),
                Op::ConstSub(c) => stack[sp - 1][..n].iter_mut().for_each(|v| *v = c - *v),
                Op::ConstDiv(c) => stack[sp - 1][..n].iter_mut().for_each(|v| *v = c / *v),
                Op::Call(_, Some(Lanes::Exp)) => lanes::exp(&mut stack[sp - 1][..n]),
                Op::Call(f, None) => stack[sp - 1][..n].iter_mut().for_each(|v| *v = f(*v)),
                Op::Add | Op::Sub | Op::Mul | Op::Div | Op::Rem | Op::Pow | Op::Atan2 => {
                    sp -= 1;
                    let (below, top) = stack.split_at_mut(sp);
                    let (l, r) = (&mut below[sp - 1][..n], &top[0][..n]);
                    let lanes = l.iter_mut().zip(r);
                    match *op {
                        Op::Add => lanes.for_each(|(l, r)| *l += r),
                        Op::Sub => lanes.for_each(|(l, r)| *l -= r),
                        Op::Mul => lanes.for_each(|(l, r)| *l *= r),
                        Op::Div => lanes.for_each(|(l, r)| *l /= r),
                        Op::Rem => lanes.for_each(|(l, r)| *l %= r),
                        Op::Pow => lanes.for_each(|(l, r)| *l = libm::pow(*l, *r)),
                        _ => lanes.for_each(|(l, r)| *l = libm::atan2(*l, *r)),
                    }
                }
                Op::Max(k) | Op::Min(k) => {
                    let k = k as usize;
                    let is_max = matches!(*op, Op::Max(_));
                    for lane in 0..n {
                        let args = stack[sp - k..sp].iter().map(|row| row[lane]);
                        stack[sp - k][lane] = if is_max {
                            args.fold(f64::NEG_INFINITY, max_of)
                        } else {
                            args.fold(f64::INFINITY, min_of)
                        };
                    }
                    sp -= k - 1;
                }
            }
        }
        out.copy_from_slice(&stack[0][..n]);
    }
}

/// [`Expression::eval_many`] as a [`pulp::WithSimd`] operation: pulp compiles it once per
/// instruction set (the batch evaluator and the lanes are `#[inline(always)]`) and runs the
/// one this CPU has. One dispatch for a call's every batch: a call per batch into code that
/// could not be inlined cost batches of 6 a fifth of their time (docs/speed.md).
struct Batches<'a> {
    f: &'a Expression,
    points: &'a [Point],
    out: &'a mut [f64],
    stack: &'a mut [[f64; BATCH]],
}

impl pulp::WithSimd for Batches<'_> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _: S) {
        let Self { f, points, out, stack } = self;
        for (points, out) in points.chunks(BATCH).zip(out.chunks_mut(BATCH)) {
            match &f.scalar {
                // Decoding the program costs a batch of a few points more than the
                // closures do (`benches/expression.rs`: 130 ns a point in threes, 90
                // one by one, 87 in sixes).
                Some(g) if points.len() < SCALAR_BELOW => {
                    for (p, out) in points.iter().zip(out) {
                        *out = g(p.x, p.y);
                    }
                }
                _ => f.eval_batch(points, out, stack),
            }
        }
    }
}

impl Surface for Expression {
    #[inline]
    fn eval(&self, p: Point) -> f64 {
        self.eval_xy(p.x, p.y)
    }

    fn eval_many(&self, points: &[Point], out: &mut [f64]) {
        Expression::eval_many(self, points, out);
    }
}
