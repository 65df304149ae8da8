//! An expression compiled into a small stack program: its operations, the check of names and
//! arguments, the folding of constants, and the functions it calls.

use super::error::{ExprErrorKind, MAX_DEPTH};
use meval::tokenizer::{Operation, Token};

#[derive(Debug, Clone, Copy)]
pub(super) enum Op {
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
    pub(super) fn pops(self) -> usize {
        match self {
            Op::Const(_) | Op::X | Op::Y => 0,
            Op::Add | Op::Sub | Op::Mul | Op::Div | Op::Rem | Op::Pow | Op::Atan2 => 2,
            Op::Max(n) | Op::Min(n) => n as usize,
            _ => 1,
        }
    }

    /// The operation that combines the top with constant `c` on its right (`right`) or left.
    pub(super) fn with_const(self, c: f64, right: bool) -> Option<Self> {
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
    pub(super) fn split_const(self) -> Option<(Self, f64, bool)> {
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
pub(super) fn fuse(program: Vec<Op>) -> Vec<Op> {
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

/// Functions of one argument, by meval's names.
pub(super) fn unary(name: &str) -> Option<fn(f64) -> f64> {
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
pub(super) enum Lanes {
    Exp,
}

pub(super) fn over_lanes(name: &str) -> Option<Lanes> {
    match name {
        "exp" => Some(Lanes::Exp),
        _ => None,
    }
}

/// How many arguments a known function takes, as text for messages, and whether `n` fits.
pub(super) fn arity(name: &str, n: usize) -> Option<(&'static str, bool)> {
    match name {
        "atan2" => Some(("2", n == 2)),
        "max" | "min" => Some(("at least 1", n >= 1)),
        _ => unary(name).map(|_| ("1", n == 1)),
    }
}

/// `max(a, b)` with one answer for every pair, on every path. `f64::max` leaves the sign of
/// a zero to the instruction the compiler picks, and the scalar and batched evaluations got
/// different ones (the fuzzer found `max(y, x, y, 0-x) % 0.5` at (0, −0) giving 0 one way and
/// −0 the other). Of equal values (+0 and −0) the first is kept; a NaN gives way to the other
/// operand, as in `f64::max`.
#[inline]
pub(super) fn max_of(a: f64, b: f64) -> f64 {
    if b > a || a.is_nan() { b } else { a }
}

/// `min(a, b)` as [`max_of`] is `max`.
#[inline]
pub(super) fn min_of(a: f64, b: f64) -> f64 {
    if b < a || a.is_nan() { b } else { a }
}

/// Rejects unknown variables and functions and wrong argument counts, returning the token
/// index of the first offender. Done on the infix tokens, where positions are still known.
pub(super) fn check_names(tokens: &[Token]) -> Result<(), (usize, ExprErrorKind)> {
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
pub(super) fn count_arguments(rest: &[Token]) -> usize {
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

pub(super) fn compile(rpn: &[Token]) -> Result<Vec<Op>, ExprErrorKind> {
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
