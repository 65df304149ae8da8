//! The compiled program as a tree of closures, for one point at a time.
//!
//! The stack program decodes every operation for every point and moves each value through a
//! stack array in memory; for one point that is most of the cost (the batch evaluator pays it
//! once per batch of up to 32 points). Here each operation is a closure that calls its
//! operands' closures and keeps the values in registers, and an operand that is a constant or
//! a variable is folded into its operator's closure. The operations, and their order on each
//! value, are the program's, so the results are the same bits.

use super::program::{Op, max_of, min_of};

/// F(x, y) for one point.
pub(super) type Scalar = Box<dyn Fn(f64, f64) -> f64 + Send + Sync>;

/// Trees taller than this stay with the stack program: evaluating a tree recurses once per
/// level, and a long chain such as `x+x+…+x` would otherwise take the thread's stack with it.
pub(super) const MAX_HEIGHT: usize = 128;

/// An operand while the tree is built: constants and variables are kept apart so that the
/// operator can fold them in instead of calling a closure for them.
enum Value {
    Const(f64),
    X,
    Y,
    Tree(Scalar),
}

impl Value {
    fn into_tree(self) -> Scalar {
        match self {
            Value::Const(c) => Box::new(move |_, _| c),
            Value::X => Box::new(|x, _| x),
            Value::Y => Box::new(|_, y| y),
            Value::Tree(f) => f,
        }
    }
}

/// The program as closures, or `None` when its tree is taller than [`MAX_HEIGHT`].
pub(super) fn build(program: &[Op]) -> Option<Scalar> {
    // Each stack slot: the operand and the height of its tree.
    let mut stack: Vec<(Value, usize)> = Vec::new();
    for op in program {
        let (value, height) = match *op {
            Op::Const(c) => (Value::Const(c), 1),
            Op::X => (Value::X, 1),
            Op::Y => (Value::Y, 1),
            Op::Neg | Op::Square | Op::Call(..) => {
                let (a, h) = stack.pop()?;
                let a = a.into_tree();
                let f: Scalar = match *op {
                    Op::Neg => Box::new(move |x, y| -a(x, y)),
                    Op::Square => Box::new(move |x, y| {
                        let v = a(x, y);
                        v * v
                    }),
                    Op::Call(g, _) => Box::new(move |x, y| g(a(x, y))),
                    _ => unreachable!("a unary operation"),
                };
                (Value::Tree(f), h + 1)
            }
            Op::AddConst(_)
            | Op::SubConst(_)
            | Op::MulConst(_)
            | Op::DivConst(_)
            | Op::ConstSub(_)
            | Op::ConstDiv(_) => {
                let (base, c, right) = op.split_const()?;
                let (a, h) = stack.pop()?;
                let tree =
                    if right { binary(base, a, Value::Const(c)) } else { binary(base, Value::Const(c), a) };
                (Value::Tree(tree), h + 1)
            }
            Op::Add | Op::Sub | Op::Mul | Op::Div | Op::Rem | Op::Pow | Op::Atan2 => {
                let (r, hr) = stack.pop()?;
                let (l, hl) = stack.pop()?;
                (Value::Tree(binary(*op, l, r)), hl.max(hr) + 1)
            }
            Op::Max(n) | Op::Min(n) => {
                let at = stack.len().checked_sub(n as usize)?;
                let args: Vec<(Value, usize)> = stack.drain(at..).collect();
                let height = args.iter().map(|&(_, h)| h).max().unwrap_or(0) + 1;
                let args: Vec<Scalar> = args.into_iter().map(|(v, _)| v.into_tree()).collect();
                let f: Scalar = if matches!(*op, Op::Max(_)) {
                    Box::new(move |x, y| args.iter().fold(f64::NEG_INFINITY, |m, a| max_of(m, a(x, y))))
                } else {
                    Box::new(move |x, y| args.iter().fold(f64::INFINITY, |m, a| min_of(m, a(x, y))))
                };
                (Value::Tree(f), height)
            }
        };
        if height > MAX_HEIGHT {
            return None;
        }
        stack.push((value, height));
    }
    let (root, _) = stack.pop()?;
    stack.is_empty().then(|| root.into_tree())
}

/// `l op r` with a constant or variable side folded in.
fn binary(op: Op, l: Value, r: Value) -> Scalar {
    macro_rules! fold {
        ($a:ident, $b:ident => $e:expr) => {
            match (l, r) {
                (Value::Const($a), Value::X) => Box::new(move |$b, _| $e),
                (Value::Const($a), Value::Y) => Box::new(move |_, $b| $e),
                (Value::X, Value::Const($b)) => Box::new(move |$a, _| $e),
                (Value::Y, Value::Const($b)) => Box::new(move |_, $a| $e),
                (Value::Const($a), Value::Tree(rf)) => Box::new(move |x, y| {
                    let $b = rf(x, y);
                    $e
                }),
                (Value::Tree(lf), Value::Const($b)) => Box::new(move |x, y| {
                    let $a = lf(x, y);
                    $e
                }),
                (l, r) => {
                    let (lf, rf) = (l.into_tree(), r.into_tree());
                    Box::new(move |x, y| {
                        let $a = lf(x, y);
                        let $b = rf(x, y);
                        $e
                    })
                }
            }
        };
    }
    match op {
        Op::Add => fold!(a, b => a + b),
        Op::Sub => fold!(a, b => a - b),
        Op::Mul => fold!(a, b => a * b),
        Op::Div => fold!(a, b => a / b),
        Op::Rem => fold!(a, b => a % b),
        Op::Pow => fold!(a, b => libm::pow(a, b)),
        _ => fold!(a, b => libm::atan2(a, b)),
    }
}
