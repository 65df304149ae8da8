//! A `meval` expression in x and y, compiled once into a small stack program and a tree of
//! closures.
//!
//! meval parses (its tokenizer and shunting-yard are public); evaluation runs our own
//! compiled form: variables are slots, functions are resolved to pointers once, and the
//! transcendental functions come from the `libm` crate, a pure-Rust port of musl's libm, so
//! the same expression gives the same bits on every machine (the platform libm may differ in
//! the last ulp). Batches run the stack program, each operation over all their points, with
//! `exp` four lanes at a time ([`lanes`]); one point runs the closures ([`closures`]), which
//! keep values in registers. All do the same operations in the same order. The compiled
//! forms are `Send + Sync`, unlike meval's bound closures.

use super::Surface;
use crate::geom::Point;
use meval::shunting_yard::{RPNError, to_rpn};
use meval::tokenizer::{Operation, ParseError, Token, tokenize};
use std::cell::RefCell;
use std::fmt;
use std::sync::{Arc, LazyLock};

mod closures;
mod hint;
mod lanes;

/// The most values an expression may hold pending at once while evaluating; deeper nesting
/// is rejected at parse time so evaluation can use a fixed stack array and never allocate.
pub const MAX_DEPTH: usize = 64;

/// A parse error and the 1-based column (in characters) where it was found.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{kind} at column {column}{}", hint.as_ref().map_or(String::new(), |h| format!("; {h}")))]
pub struct ExprError {
    /// 1-based character column; one past the end for errors at the end of the text.
    pub column: usize,
    /// What is wrong.
    pub kind: ExprErrorKind,
    /// What to write instead, for a common slip (`2x`, `x**2`, `log`, `|x|`, an open `(`).
    pub hint: Option<String>,
}

/// What is wrong with an expression.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ExprErrorKind {
    /// The text is empty or blank.
    Empty,
    /// A character that cannot stand here.
    UnexpectedToken(String),
    /// The text ends inside parentheses.
    MissingClosingParens(usize),
    /// The text ends where an operand is expected (after an operator, say).
    MissingOperand,
    /// A name other than x, y, pi and e.
    UnknownVariable(String),
    /// A function meval does not provide.
    UnknownFunction(String),
    /// A function called with the wrong number of arguments.
    WrongArity {
        /// The function.
        name: String,
        /// What it takes, e.g. "1" or "at least 1".
        expected: &'static str,
        /// What it got.
        got: usize,
    },
    /// Parentheses or commas that do not pair up.
    Unbalanced(&'static str),
    /// Nesting deeper than `MAX_DEPTH` (64) pending values.
    TooDeep,
}

impl fmt::Display for ExprErrorKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Empty => f.write_str("expression is empty"),
            Self::UnexpectedToken(s) => write!(f, "unexpected `{s}`"),
            Self::MissingClosingParens(1) => f.write_str("missing 1 closing parenthesis"),
            Self::MissingClosingParens(n) => write!(f, "missing {n} closing parentheses"),
            Self::MissingOperand => f.write_str("expression ends where an operand is expected"),
            Self::UnknownVariable(v) => write!(f, "unknown variable `{v}` (use x and y)"),
            Self::UnknownFunction(v) => write!(f, "unknown function `{v}`"),
            Self::WrongArity { name, expected, got } => {
                write!(f, "function `{name}` takes {expected} argument(s), got {got}")
            }
            Self::Unbalanced(what) => f.write_str(what),
            Self::TooDeep => write!(f, "expression nests deeper than {MAX_DEPTH} levels"),
        }
    }
}

#[derive(Debug, Clone, Copy)]
enum Op {
    Const(f64),
    X,
    Y,
    Neg,
    /// `^2`: one multiplication instead of a call to `pow`.
    Square,
    Add,
    Sub,
    Mul,
    Div,
    Rem,
    Pow,
    /// A function of one argument, and its form over a batch's lanes where one exists.
    Call(fn(f64) -> f64, Option<Lanes>),
    Atan2,
    Max(u32),
    Min(u32),
    /// `v + c`, `v − c`, `v · c`, `v / c`, `c − v` and `c / v` for the value v on top and a
    /// constant c: one operation where the program pushed the constant and then combined it
    /// ([`fuse`]). `c + v` and `c · v` become `v + c` and `v · c`, the same bits (IEEE
    /// addition and multiplication commute, and a constant is never NaN).
    AddConst(f64),
    SubConst(f64),
    MulConst(f64),
    DivConst(f64),
    ConstSub(f64),
    ConstDiv(f64),
}

impl Op {
    /// How many values it takes off the stack (each operation pushes one).
    fn pops(self) -> usize {
        match self {
            Op::Const(_) | Op::X | Op::Y => 0,
            Op::Add | Op::Sub | Op::Mul | Op::Div | Op::Rem | Op::Pow | Op::Atan2 => 2,
            Op::Max(n) | Op::Min(n) => n as usize,
            _ => 1,
        }
    }

    /// The operation that combines the top with constant `c` on its right (`right`) or left.
    fn with_const(self, c: f64, right: bool) -> Option<Self> {
        Some(match (self, right) {
            (Op::Add, _) => Op::AddConst(c),
            (Op::Mul, _) => Op::MulConst(c),
            (Op::Sub, true) => Op::SubConst(c),
            (Op::Div, true) => Op::DivConst(c),
            (Op::Sub, false) => Op::ConstSub(c),
            (Op::Div, false) => Op::ConstDiv(c),
            _ => return None,
        })
    }

    /// The inverse of [`Op::with_const`]: the plain operation, the constant, and whether it
    /// stands on the right.
    fn split_const(self) -> Option<(Self, f64, bool)> {
        Some(match self {
            Op::AddConst(c) => (Op::Add, c, true),
            Op::SubConst(c) => (Op::Sub, c, true),
            Op::MulConst(c) => (Op::Mul, c, true),
            Op::DivConst(c) => (Op::Div, c, true),
            Op::ConstSub(c) => (Op::Sub, c, false),
            Op::ConstDiv(c) => (Op::Div, c, false),
            _ => return None,
        })
    }
}

/// `program` with each constant operand of `+ − · /` folded into its operator, on either
/// side: Franke's function goes from 78 operations to 54, each a pass over a batch's lanes,
/// and every value is computed by the same operation as before.
fn fuse(program: Vec<Op>) -> Vec<Op> {
    let mut out: Vec<Op> = Vec::with_capacity(program.len());
    // Where in `out` each value on the stack begins (its operand's first operation).
    let mut starts: Vec<usize> = Vec::new();
    for op in program {
        let pops = op.pops();
        let at = starts.len() - pops;
        let start = starts.get(at).copied().unwrap_or(out.len());
        if pops == 2 {
            let (left, right) = (starts[at], starts[at + 1]);
            // The operand at `i` if it is one constant alone (it ends where `end` begins).
            let lone = |i: usize, end: usize| match out[i] {
                Op::Const(c) if i + 1 == end => Some(c),
                _ => None,
            };
            // The right operand is a lone constant, or the left one is (a removal that moves
            // only the right operand, at most MAX_DEPTH levels deep).
            let fused = lone(right, out.len())
                .and_then(|c| op.with_const(c, true))
                .map(|f| (right, f))
                .or_else(|| lone(left, right).and_then(|c| op.with_const(c, false)).map(|f| (left, f)));
            if let Some((removed, f)) = fused {
                out.remove(removed);
                out.push(f);
                starts.truncate(at);
                starts.push(left);
                continue;
            }
        }
        out.push(op);
        starts.truncate(at);
        starts.push(start);
    }
    out
}

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
    text: String,
    program: Vec<Op>,
    /// The program as closures, for one point at a time (absent for a very tall tree).
    scalar: Option<Arc<dyn Fn(f64, f64) -> f64 + Send + Sync>>,
}

impl fmt::Debug for Expression {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_tuple("Expression").field(&self.text).finish()
    }
}

/// Functions of one argument, by meval's names.
fn unary(name: &str) -> Option<fn(f64) -> f64> {
    Some(match name {
        "sqrt" => f64::sqrt,
        "exp" => libm::exp,
        "ln" => libm::log,
        "abs" => f64::abs,
        "sin" => libm::sin,
        "cos" => libm::cos,
        "tan" => libm::tan,
        "asin" => libm::asin,
        "acos" => libm::acos,
        "atan" => libm::atan,
        "sinh" => libm::sinh,
        "cosh" => libm::cosh,
        "tanh" => libm::tanh,
        "asinh" => libm::asinh,
        "acosh" => libm::acosh,
        "atanh" => libm::atanh,
        "floor" => f64::floor,
        "ceil" => f64::ceil,
        "round" => f64::round,
        "signum" => f64::signum,
        _ => return None,
    })
}

/// A function of one argument that a batch runs over its lanes at once, bit for bit as
/// [`unary`]'s one value at a time. An enum rather than a pointer, so that the lanes are
/// inlined into the batch evaluator and compiled for its instruction set.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Lanes {
    Exp,
}

fn over_lanes(name: &str) -> Option<Lanes> {
    match name {
        "exp" => Some(Lanes::Exp),
        _ => None,
    }
}

/// How many arguments a known function takes, as text for messages, and whether `n` fits.
fn arity(name: &str, n: usize) -> Option<(&'static str, bool)> {
    match name {
        "atan2" => Some(("2", n == 2)),
        "max" | "min" => Some(("at least 1", n >= 1)),
        _ => unary(name).map(|_| ("1", n == 1)),
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
    fn run_program(&self, x: f64, y: f64) -> f64 {
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
const SCALAR_BELOW: usize = 6;

/// `max(a, b)` with one answer for every pair, on every path. `f64::max` leaves the sign of
/// a zero to the instruction the compiler picks, and the scalar and batched evaluations got
/// different ones (the fuzzer found `max(y, x, y, 0-x) % 0.5` at (0, −0) giving 0 one way and
/// −0 the other). Of equal values (+0 and −0) the first is kept; a NaN gives way to the other
/// operand, as in `f64::max`.
#[inline]
fn max_of(a: f64, b: f64) -> f64 {
    if b > a || a.is_nan() { b } else { a }
}

/// `min(a, b)` as [`max_of`] is `max`.
#[inline]
fn min_of(a: f64, b: f64) -> f64 {
    if b < a || a.is_nan() { b } else { a }
}

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

    fn eval_many_on(&self, arch: pulp::Arch, points: &[Point], out: &mut [f64]) {
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

/// Rejects unknown variables and functions and wrong argument counts, returning the token
/// index of the first offender. Done on the infix tokens, where positions are still known.
fn check_names(tokens: &[Token]) -> Result<(), (usize, ExprErrorKind)> {
    for (index, token) in tokens.iter().enumerate() {
        match token {
            Token::Var(name) if !matches!(name.as_str(), "x" | "y" | "pi" | "e") => {
                return Err((index, ExprErrorKind::UnknownVariable(name.clone())));
            }
            Token::Func(name, _) => {
                let got = count_arguments(&tokens[index + 1..]);
                match arity(name, got) {
                    None => return Err((index, ExprErrorKind::UnknownFunction(name.clone()))),
                    Some((expected, false)) => {
                        let kind = ExprErrorKind::WrongArity { name: name.clone(), expected, got };
                        return Err((index, kind));
                    }
                    Some((_, true)) => {}
                }
            }
            _ => {}
        }
    }
    Ok(())
}

/// Arguments of a call whose `name(` token was just consumed: top-level commas + 1, or 0 for
/// an empty list.
fn count_arguments(rest: &[Token]) -> usize {
    let (mut depth, mut commas) = (1usize, 0usize);
    for (i, token) in rest.iter().enumerate() {
        match token {
            Token::LParen | Token::Func(..) => depth += 1,
            Token::RParen => {
                depth -= 1;
                if depth == 0 {
                    return if i == 0 { 0 } else { commas + 1 };
                }
            }
            Token::Comma if depth == 1 => commas += 1,
            _ => {}
        }
    }
    commas + 1
}

fn compile(rpn: &[Token]) -> Result<Vec<Op>, ExprErrorKind> {
    let mut program = Vec::with_capacity(rpn.len());
    let mut depth = 0usize;
    for token in rpn {
        let op = match token {
            Token::Number(v) => Op::Const(*v),
            Token::Var(name) => match name.as_str() {
                "x" => Op::X,
                "y" => Op::Y,
                "pi" => Op::Const(std::f64::consts::PI),
                "e" => Op::Const(std::f64::consts::E),
                other => return Err(ExprErrorKind::UnknownVariable(other.to_owned())),
            },
            Token::Unary(Operation::Plus) => continue,
            Token::Unary(_) => Op::Neg,
            Token::Binary(op) => match op {
                Operation::Plus => Op::Add,
                Operation::Minus => Op::Sub,
                Operation::Times => Op::Mul,
                Operation::Div => Op::Div,
                Operation::Rem => Op::Rem,
                Operation::Pow => Op::Pow,
            },
            Token::Func(name, Some(n)) => {
                let n = *n;
                match (name.as_str(), unary(name)) {
                    (_, Some(f)) if n == 1 => Op::Call(f, over_lanes(name)),
                    ("atan2", _) if n == 2 => Op::Atan2,
                    ("max", _) if n >= 1 => Op::Max(n as u32),
                    ("min", _) if n >= 1 => Op::Min(n as u32),
                    _ => return Err(ExprErrorKind::UnknownFunction(name.clone())),
                }
            }
            _ => return Err(ExprErrorKind::Unbalanced("malformed expression")),
        };
        let pops = op.pops();
        if depth < pops {
            return Err(ExprErrorKind::Unbalanced("operator without an operand"));
        }
        depth = depth - pops + 1;
        if depth > MAX_DEPTH {
            return Err(ExprErrorKind::TooDeep);
        }
        // `t^2`, the commonest power by far (Franke has six), is a multiplication: exact to
        // the last bit like any correctly rounded square, and several times cheaper.
        if matches!(op, Op::Pow) && matches!(program.last(), Some(Op::Const(c)) if *c == 2.0) {
            program.pop();
            program.push(Op::Square);
            continue;
        }
        program.push(op);
    }
    if depth != 1 {
        return Err(ExprErrorKind::Unbalanced("operands without an operator"));
    }
    Ok(program)
}

/// 1-based character column of byte offset `byte`.
fn column_of(text: &str, byte: usize) -> usize {
    text[..byte.min(text.len())].chars().count() + 1
}

/// Byte offset where each token of meval's tokenizer starts, for text it accepted: numbers
/// (digits, optional fraction, optional exponent), `name(` as one token, names, and single
/// characters for operators, parentheses and commas.
fn token_starts(text: &str) -> Vec<usize> {
    let bytes = text.as_bytes();
    let digits = |mut i: usize| {
        while i < bytes.len() && bytes[i].is_ascii_digit() {
            i += 1;
        }
        i
    };
    let mut starts = Vec::new();
    let mut i = 0;
    while i < bytes.len() {
        let c = bytes[i];
        if c.is_ascii_whitespace() {
            i += 1;
            continue;
        }
        starts.push(i);
        if c.is_ascii_digit() {
            i = digits(i);
            if bytes.get(i) == Some(&b'.') {
                i = digits(i + 1);
            }
            if matches!(bytes.get(i), Some(b'e' | b'E')) {
                let sign = usize::from(matches!(bytes.get(i + 1), Some(b'+' | b'-')));
                if bytes.get(i + 1 + sign).is_some_and(u8::is_ascii_digit) {
                    i = digits(i + 1 + sign);
                }
            }
        } else if c.is_ascii_alphabetic() || c == b'_' {
            while i < bytes.len() && (bytes[i].is_ascii_alphanumeric() || bytes[i] == b'_') {
                i += 1;
            }
            let mut j = i;
            while j < bytes.len() && bytes[j].is_ascii_whitespace() {
                j += 1;
            }
            if bytes.get(j) == Some(&b'(') {
                i = j + 1;
            }
        } else {
            i += 1;
        }
    }
    starts
}

#[cfg(test)]
mod tests {
    use super::*;
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
        let points =
            [Point::new(0.0, -0.0), Point::new(-0.0, 0.0), Point::new(-0.0, -0.0), Point::new(0.0, 0.0)];
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
                (inner.clone(), inner.clone(), "max|min|atan2")
                    .prop_map(|(a, b, f)| format!("{f}({a}, {b})")),
                (inner.clone(), inner.clone(), inner.clone())
                    .prop_map(|(a, b, c)| format!("min({a}, {b}, {c})")),
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
}
