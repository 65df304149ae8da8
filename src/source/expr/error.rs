//! Why an expression does not parse, and where: the 1-based column, found once from meval's
//! byte offsets.

use std::fmt;

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

/// 1-based character column of byte offset `byte`.
pub(super) fn column_of(text: &str, byte: usize) -> usize {
    text[..byte.min(text.len())].chars().count() + 1
}

/// Byte offset where each token of meval's tokenizer starts, for text it accepted: numbers
/// (digits, optional fraction, optional exponent), `name(` as one token, names, and single
/// characters for operators, parentheses and commas.
pub(super) fn token_starts(text: &str) -> Vec<usize> {
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
