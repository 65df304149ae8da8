//! meshfit's JSON grid, `{"nx": .., "ny": .., "values": [..]}`, bottom row first.
//!
//! The values are read through a seed that keeps at most `max_points` of them and counts the
//! rest, so a body of a million numbers cannot grow a vector past the limit; the first element
//! that is not a number is remembered, so the error can name its (i, j) once nx is known.
//! The API's JSON requests carry the same array, decoded here by [`decode_values`].

use super::assemble::{Rows, check_size, into_grid};
use super::error::{GridFileError, detail};
use super::kind::GridFileKind;
use crate::source::Grid;
use serde::de::{self, DeserializeSeed, MapAccess, SeqAccess, Visitor};
use std::cell::Cell;
use std::fmt;

const KIND: GridFileKind = GridFileKind::Json;

pub(super) fn decode(bytes: &[u8], max_points: usize) -> Result<Grid, GridFileError> {
    let overflow = Cell::new(None);
    let corrupt = |e: serde_json::Error| match overflow.get() {
        Some(index) => GridFileError::OutOfRange { index, at: None },
        None => GridFileError::Corrupt { kind: KIND, detail: detail(e) },
    };
    let mut de = serde_json::Deserializer::from_slice(bytes);
    let file = FileSeed { limit: max_points, overflow: &overflow }.deserialize(&mut de).map_err(corrupt)?;
    de.end().map_err(corrupt)?;
    let shape = check_size(file.nx, file.ny, max_points)?;
    grid_of(shape, file.values)
}

/// A grid from the JSON text of its `values` array (bottom row first) and its shape: the
/// API's JSON requests. nx·ny is checked against `max_points` before the array is parsed.
///
/// # Errors
/// As for a JSON grid file: nx·ny above the limit or nx, ny below 2, a count that does not
/// match, an element that is not a number or a value that is not finite (naming its (i, j)).
pub fn decode_values(values: &str, nx: u64, ny: u64, max_points: usize) -> Result<Grid, GridFileError> {
    let shape = check_size(nx, ny, max_points)?;
    let overflow = Cell::new(None);
    let corrupt = |e: serde_json::Error| match overflow.get() {
        Some(index) => GridFileError::OutOfRange { index, at: Some(shape.at(index)) },
        None => GridFileError::Corrupt { kind: KIND, detail: detail(e) },
    };
    let mut de = serde_json::Deserializer::from_str(values);
    let values =
        ValuesSeed { limit: max_points, overflow: &overflow }.deserialize(&mut de).map_err(corrupt)?;
    de.end().map_err(corrupt)?;
    grid_of(shape, values)
}

fn grid_of(shape: super::assemble::Shape, values: Values) -> Result<Grid, GridFileError> {
    let expected = shape.points() as u64;
    if let Some((0, "an array")) = values.first_bad {
        return Err(GridFileError::Nested { rows: values.count });
    }
    if values.count != expected {
        let (unit, from, got) = ("values", "nx and ny", values.count);
        return Err(GridFileError::SizeMismatch { kind: KIND, unit, from, expected, got });
    }
    if let Some((index, found)) = values.first_bad {
        let [i, j] = shape.at(index);
        return Err(GridFileError::NotANumber { i, j, index, found });
    }
    into_grid(KIND, shape, Rows::BottomFirst, values.kept, None)
}

/// The file as parsed.
struct File {
    nx: u64,
    ny: u64,
    values: Values,
}

/// An array of values as parsed: the first `limit` kept (a non-number as NaN), all counted.
struct Values {
    kept: Vec<f64>,
    count: u64,
    /// Position and JSON kind of the first element that is not a number.
    first_bad: Option<(u64, &'static str)>,
}

#[derive(serde::Deserialize)]
#[serde(field_identifier, rename_all = "lowercase")]
enum Field {
    Nx,
    Ny,
    Values,
}

struct FileSeed<'c> {
    limit: usize,
    overflow: &'c Cell<Option<u64>>,
}

impl<'de> DeserializeSeed<'de> for FileSeed<'_> {
    type Value = File;

    fn deserialize<D: de::Deserializer<'de>>(self, d: D) -> Result<File, D::Error> {
        d.deserialize_map(self)
    }
}

impl<'de> Visitor<'de> for FileSeed<'_> {
    type Value = File;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(r#"{"nx": .., "ny": .., "values": [..]}"#)
    }

    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<File, A::Error> {
        let (mut nx, mut ny, mut values) = (None, None, None);
        // Unknown keys are refused by `Field`, so a typo never passes silently.
        while let Some(field) = map.next_key::<Field>()? {
            match field {
                Field::Nx if nx.is_some() => return Err(de::Error::duplicate_field("nx")),
                Field::Ny if ny.is_some() => return Err(de::Error::duplicate_field("ny")),
                Field::Values if values.is_some() => return Err(de::Error::duplicate_field("values")),
                Field::Nx => nx = Some(map.next_value()?),
                Field::Ny => ny = Some(map.next_value()?),
                Field::Values => {
                    let seed = ValuesSeed { limit: self.limit, overflow: self.overflow };
                    values = Some(map.next_value_seed(seed)?);
                }
            }
        }
        let nx = nx.ok_or_else(|| de::Error::missing_field("nx"))?;
        let ny = ny.ok_or_else(|| de::Error::missing_field("ny"))?;
        let values = values.ok_or_else(|| de::Error::missing_field("values"))?;
        Ok(File { nx, ny, values })
    }
}

/// The values, with where a number out of f64's range was met (serde_json fails on it, and
/// its error says neither which value nor why).
struct ValuesSeed<'c> {
    limit: usize,
    overflow: &'c Cell<Option<u64>>,
}

impl<'de> DeserializeSeed<'de> for ValuesSeed<'_> {
    type Value = Values;

    fn deserialize<D: de::Deserializer<'de>>(self, d: D) -> Result<Self::Value, D::Error> {
        d.deserialize_seq(self)
    }
}

impl<'de> Visitor<'de> for ValuesSeed<'_> {
    type Value = Values;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("an array of numbers")
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Self::Value, A::Error> {
        let mut values = Values { kept: Vec::new(), count: 0, first_bad: None };
        loop {
            let element = match seq.next_element::<Element>() {
                Ok(Some(element)) => element,
                Ok(None) => break,
                Err(e) => {
                    if e.to_string().starts_with("number out of range") {
                        self.overflow.set(Some(values.count));
                    }
                    return Err(e);
                }
            };
            let v = match element {
                Element::Number(v) => v,
                Element::Bad(kind) => {
                    values.first_bad.get_or_insert((values.count, kind));
                    f64::NAN
                }
            };
            if values.kept.len() < self.limit {
                values.kept.push(v);
            }
            values.count += 1;
        }
        Ok(values)
    }
}

/// One element of the values: a number, or the JSON kind of what it is instead.
enum Element {
    Number(f64),
    Bad(&'static str),
}

impl<'de> de::Deserialize<'de> for Element {
    fn deserialize<D: de::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = Element;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("a number")
            }
            fn visit_f64<E>(self, v: f64) -> Result<Element, E> {
                Ok(Element::Number(v))
            }
            fn visit_i64<E>(self, v: i64) -> Result<Element, E> {
                Ok(Element::Number(v as f64))
            }
            fn visit_u64<E>(self, v: u64) -> Result<Element, E> {
                Ok(Element::Number(v as f64))
            }
            fn visit_unit<E>(self) -> Result<Element, E> {
                Ok(Element::Bad("null"))
            }
            fn visit_bool<E>(self, _: bool) -> Result<Element, E> {
                Ok(Element::Bad("a boolean"))
            }
            fn visit_str<E>(self, _: &str) -> Result<Element, E> {
                Ok(Element::Bad("a string"))
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Element, A::Error> {
                while seq.next_element::<de::IgnoredAny>()?.is_some() {}
                Ok(Element::Bad("an array"))
            }
            fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Element, A::Error> {
                while map.next_entry::<de::IgnoredAny, de::IgnoredAny>()?.is_some() {}
                Ok(Element::Bad("an object"))
            }
        }
        d.deserialize_any(V)
    }
}
