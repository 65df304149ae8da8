//! The fix for a common slip in an expression, said with its error: implicit multiplication,
//! `**`, another language's name for a function meval spells otherwise, `|x|`, a bracket
//! meval does not group with, a parenthesis left open.

use super::error::{ExprError, ExprErrorKind};
use super::program::arity;

/// What to write instead, when the error is one of the slips this knows.
pub(super) fn hint(text: &str, error: &ExprError) -> Option<String> {
    let chars: Vec<char> = text.chars().collect();
    let at = error.column.saturating_sub(1).min(chars.len());
    match &error.kind {
        ExprErrorKind::UnexpectedToken(found) => unexpected(&chars, at, found.chars().next()?),
        ExprErrorKind::UnknownFunction(name) => function(name),
        ExprErrorKind::UnknownVariable(name) => variable(name),
        ExprErrorKind::MissingClosingParens(_) => {
            let open = unclosed(&chars)?;
            Some(format!("the `(` at column {} is not closed", open + 1))
        }
        ExprErrorKind::Unbalanced("operands without an operator") => {
            Some("meval has no implicit multiplication: write `*` between factors, as in `2*x*y`".into())
        }
        _ => None,
    }
}

/// A character the tokenizer stopped at, `found` at char index `at`.
fn unexpected(chars: &[char], at: usize, found: char) -> Option<String> {
    let before = chars[..at].iter().rposition(|c| !c.is_whitespace());
    match (before.map(|i| chars[i]), found) {
        (Some('*'), '*') => Some("powers are written with `^`: `x^2`, not `x**2`".into()),
        (_, '|') => Some("write an absolute value as `abs(x)`".into()),
        (_, '[' | ']' | '{' | '}') => Some("group with `(` and `)`; meval has no other brackets".into()),
        (_, ')') if unclosed(&chars[..at]).is_none() => Some("no `(` before it is left open".into()),
        (Some(c), f)
            if (c.is_alphanumeric() || c == '.' || c == ')') && (f.is_alphanumeric() || f == '(') =>
        {
            let end = before? + 1;
            let operand = |c: &char| c.is_alphanumeric() || *c == '.' || *c == '_';
            let start = match c {
                ')' => partner(chars, end - 1)?,
                _ => chars[..end].iter().rposition(|c| !operand(c)).map_or(0, |i| i + 1),
            };
            let left: String = chars[start..end].iter().collect();
            if arity(&left, 1).is_some() {
                return Some(format!("a function's argument goes in parentheses: `{left}(…)`"));
            }
            let next = match f {
                '(' => partner(chars, at).map_or(at + 1, |close| close + 1),
                _ => at + chars[at..].iter().take_while(|c| operand(c)).count(),
            };
            let right: String = chars[at..next].iter().collect();
            Some(format!("meval has no implicit multiplication: write `{left}*{right}`"))
        }
        _ => None,
    }
}

/// A function name from another language, with meval's spelling.
fn function(name: &str) -> Option<String> {
    let fix = match name {
        "log" => "the natural logarithm is `ln(x)`; log10(x) is `ln(x)/ln(10)`",
        "log10" => "write log10(x) as `ln(x)/ln(10)`",
        "log2" => "write log2(x) as `ln(x)/ln(2)`",
        "fabs" | "absolute" => "the absolute value is `abs(x)`",
        "pow" | "power" => "powers are written with `^`: `x^y`",
        "sqr" => "a square is `x^2`",
        "arcsin" => "the arcsine is `asin(x)`",
        "arccos" => "the arccosine is `acos(x)`",
        "arctan" | "atn" => "the arctangent is `atan(x)`",
        "sgn" | "sign" => "the sign is `signum(x)`",
        "ceiling" => "rounding up is `ceil(x)`",
        "mod" | "fmod" => "the remainder is `x % y`",
        _ => {
            let lower = name.to_lowercase();
            return (lower != name && arity(&lower, 1).is_some())
                .then(|| format!("function names are lowercase: `{lower}`"));
        }
    };
    Some(fix.into())
}

/// A variable name that is a product of x and y, or a known name in another case.
fn variable(name: &str) -> Option<String> {
    match name {
        "X" | "Y" | "PI" | "Pi" | "E" => Some(format!("names are lowercase: `{}`", name.to_lowercase())),
        _ if name.len() > 1 && name.chars().all(|c| c == 'x' || c == 'y') => {
            let product: Vec<String> = name.chars().map(String::from).collect();
            Some(format!("meval has no implicit multiplication: write `{}`", product.join("*")))
        }
        _ => None,
    }
}

/// The char index of the last `(` that no `)` closes.
fn unclosed(chars: &[char]) -> Option<usize> {
    let mut open = Vec::new();
    for (i, &c) in chars.iter().enumerate() {
        match c {
            '(' => open.push(i),
            ')' => {
                open.pop();
            }
            _ => {}
        }
    }
    open.pop()
}

/// The index of the parenthesis that pairs with the one at `at`: forward from a `(`,
/// backward from a `)`.
fn partner(chars: &[char], at: usize) -> Option<usize> {
    let (same, step) = if chars[at] == '(' { ('(', 1) } else { (')', -1) };
    let mut depth = 0usize;
    let mut i = at as isize;
    while let Some(&c) = usize::try_from(i).ok().and_then(|i| chars.get(i)) {
        if c == same {
            depth += 1;
        } else if c == '(' || c == ')' {
            depth -= 1;
            if depth == 0 {
                return Some(i as usize);
            }
        }
        i += step;
    }
    None
}

#[cfg(test)]
mod tests {
    use crate::source::Expression;

    /// The message for `text`, which must not parse.
    fn message(text: &str) -> String {
        Expression::parse(text).map(|_| ()).unwrap_err().to_string()
    }

    #[test]
    fn common_slips_are_answered_with_the_fix() {
        let cases = [
            ("2x+y", "write `2*x`"),
            ("3.5sin(x)", "write `3.5*sin`"),
            ("2(x+1)", "write `2*(x+1)`"),
            ("(x+1)(x-1)", "write `(x+1)*(x-1)`"),
            ("x**2", "`^`"),
            ("log(x)", "`ln(x)`"),
            ("fabs(x - 1)", "`abs(x)`"),
            ("|x|", "`abs(x)`"),
            ("Sin(x)", "`sin`"),
            ("X + 1", "`x`"),
            ("xy", "`x*y`"),
            ("x y", "write `x*y`"),
            ("sin x", "`sin(…)`"),
            ("x + 1)", "no `(`"),
            ("[x + 1]", "group with `(` and `)`"),
            ("sin((x + 1) * y", "the `(` at column 4 is not closed"),
        ];
        for (text, fix) in cases {
            let m = message(text);
            assert!(m.contains(fix), "{text}: {m}");
        }
    }

    #[test]
    fn other_errors_get_no_hint() {
        // A hint says what to write; an error it does not know gets none, not a guess.
        for text in ["x + ", "foo(x)", "x + q", "max()"] {
            let e = Expression::parse(text).map(|_| ()).unwrap_err();
            assert_eq!(e.hint, None, "{text}: {e}");
        }
    }
}
