//! meshfit's JSON grid, `{"nx": .., "ny": .., "values": [..]}`, bottom row first.
//!
//! The values are read through a seed that keeps at most `max_points` of them and counts the
//! rest, so a body of a million numbers cannot grow a vector past the limit.

use super::{GridFileError, GridFileKind, Rows, check_size, detail, into_grid};
use crate::source::Grid;
use serde::de::{self, DeserializeSeed, MapAccess, SeqAccess, Visitor};
use std::fmt;

const KIND: GridFileKind = GridFileKind::Json;

pub(super) fn decode(bytes: &[u8], max_points: usize) -> Result<Grid, GridFileError> {
    let corrupt = |e: serde_json::Error| GridFileError::Corrupt { kind: KIND, detail: detail(e) };
    let mut de = serde_json::Deserializer::from_slice(bytes);
    let file = FileSeed { limit: max_points }.deserialize(&mut de).map_err(corrupt)?;
    de.end().map_err(corrupt)?;
    let shape = check_size(file.nx, file.ny, max_points)?;
    let expected = shape.points() as u64;
    if file.count != expected {
        return Err(GridFileError::SizeMismatch {
            kind: KIND,
            unit: "values",
            from: "nx and ny",
            expected,
            got: file.count,
        });
    }
    into_grid(KIND, shape, Rows::BottomFirst, file.values, None)
}

/// The file as parsed: `values` holds the first `limit` numbers, `count` all of them.
struct File {
    nx: u64,
    ny: u64,
    values: Vec<f64>,
    count: u64,
}

#[derive(serde::Deserialize)]
#[serde(field_identifier, rename_all = "lowercase")]
enum Field {
    Nx,
    Ny,
    Values,
}

struct FileSeed {
    limit: usize,
}

impl<'de> DeserializeSeed<'de> for FileSeed {
    type Value = File;

    fn deserialize<D: de::Deserializer<'de>>(self, d: D) -> Result<File, D::Error> {
        d.deserialize_map(self)
    }
}

impl<'de> Visitor<'de> for FileSeed {
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
                Field::Values => values = Some(map.next_value_seed(ValuesSeed { limit: self.limit })?),
            }
        }
        let nx = nx.ok_or_else(|| de::Error::missing_field("nx"))?;
        let ny = ny.ok_or_else(|| de::Error::missing_field("ny"))?;
        let (values, count) = values.ok_or_else(|| de::Error::missing_field("values"))?;
        Ok(File { nx, ny, values, count })
    }
}

struct ValuesSeed {
    limit: usize,
}

impl<'de> DeserializeSeed<'de> for ValuesSeed {
    type Value = (Vec<f64>, u64);

    fn deserialize<D: de::Deserializer<'de>>(self, d: D) -> Result<Self::Value, D::Error> {
        d.deserialize_seq(self)
    }
}

impl<'de> Visitor<'de> for ValuesSeed {
    type Value = (Vec<f64>, u64);

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("an array of numbers")
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Self::Value, A::Error> {
        let (mut values, mut count) = (Vec::new(), 0u64);
        while let Some(v) = seq.next_element::<f64>()? {
            if values.len() < self.limit {
                values.push(v);
            }
            count += 1;
        }
        Ok((values, count))
    }
}
