//! The compact binary form of a [`RunResult`], as stores keep it: little-endian arrays behind a
//! short header, and a SHA-256 of everything before it at the end.
//!
//! ```text
//! magic "MESHFIT\0" · u32 version · u32 flags (bit 1: trace)
//! u64 vertices · u64 triangles · u32 id length · id · u32 stats length · stats (JSON) ·
//! u32 fields length · fields (JSON: each field's name, unit, location, … without values)
//! vertices (x, y, z as f64) · triangles (3 × u32) ·
//! each field's values in order (f64, components per vertex or per triangle)
//! [trace (flag bit 1): u8 method · u8 criterion · u8 stop · u8 on nodes · u8 has min angle ·
//!  f64 min angle (0 without one) · u64 base evaluations ·
//!  u64 checks · u64 steps · u64 estimates · worst (f64 per check) · split half-edges (u32 per
//!  step) · evaluations (u64 per step) · estimates (u32 triangle, f64 error) ·
//!  estimate ends (u32 per step, plus one)]
//! SHA-256 of all the above
//! ```
//! The checksum covers the header, the id and the stats too, so a file renamed to another id
//! or with edited stats is refused like one with a flipped bit in the arrays.

use super::field::{Field, Location};
use super::finished::RunResult;
use crate::geom::Vertex;
use crate::refine::trace::Trace;
use crate::refine::{Criterion, Method, StopReason};
use sha2::{Digest, Sha256};
use std::io::{self, Write};
use std::sync::Arc;

const MAGIC: &[u8; 8] = b"MESHFIT\0";
const VERSION: u32 = 5;
const HAS_TRACE: u32 = 2;
const CHECKSUM_LEN: usize = 32;

/// Why bytes are not the compact form of a result with the expected id.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum CompactError {
    /// Not this format, or another version of it.
    #[error("not a meshfit result (version {VERSION})")]
    Format,
    /// Shorter or longer than its header says.
    #[error("{0}")]
    Length(String),
    /// The checksum does not match the contents.
    #[error("checksum mismatch")]
    Checksum,
    /// A well-formed result of another id.
    #[error("the file holds result {0}")]
    Id(String),
    /// The stats are not valid.
    #[error("stats: {0}")]
    Stats(String),
    /// The fields' descriptions are not valid.
    #[error("fields: {0}")]
    Fields(String),
    /// A triangle names a vertex that is not there.
    #[error("triangle {0} names a vertex out of range")]
    Triangle(usize),
}

/// Hashes what passes through to the writer.
struct Hashing<W> {
    out: W,
    hash: Sha256,
    written: u64,
}

impl<W: Write> Write for Hashing<W> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let n = self.out.write(buf)?;
        self.hash.update(&buf[..n]);
        self.written += n as u64;
        Ok(n)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.out.flush()
    }
}

/// The number of bytes [`write()`] writes for `result` under `id`, found without writing them.
pub fn size(result: &RunResult, id: &str) -> u64 {
    let stats = serde_json::to_vec(&result.stats).map_or(0, |s| s.len()) as u64;
    let fields = serde_json::to_vec(&result.fields).map_or(0, |s| s.len()) as u64;
    let (nv, nt) = (result.vertices.len() as u64, result.triangles.len() as u64);
    let values = result.fields.iter().map(|f| 8 * f.values.len() as u64).sum::<u64>();
    let trace = result.trace.as_ref().map_or(0, |t| {
        let (checks, steps, estimates) =
            (t.worst.len() as u64, t.splits.len() as u64, t.estimates.len() as u64);
        3 + 1 + 1 + 8 + 4 * 8 + 8 * checks + 12 * steps + 12 * estimates + 4 * (steps + 1)
    });
    let header = MAGIC.len() as u64 + 4 + 4 + 8 + 8 + 4 + id.len() as u64 + 4 + stats + 4 + fields;
    header + 24 * nv + 12 * nt + values + trace + CHECKSUM_LEN as u64
}

/// Writes `result`, stored under `id`, to `out` and returns the bytes written.
///
/// # Errors
/// Whatever writing to `out` returns.
pub fn write(result: &RunResult, id: &str, out: impl Write) -> io::Result<u64> {
    let stats = serde_json::to_vec(&result.stats).map_err(io::Error::other)?;
    let fields = serde_json::to_vec(&result.fields).map_err(io::Error::other)?;
    let mut w = Hashing { out, hash: Sha256::new(), written: 0 };
    let flags = if result.trace.is_some() { HAS_TRACE } else { 0 };
    w.write_all(MAGIC)?;
    w.write_all(&VERSION.to_le_bytes())?;
    w.write_all(&flags.to_le_bytes())?;
    w.write_all(&(result.vertices.len() as u64).to_le_bytes())?;
    w.write_all(&(result.triangles.len() as u64).to_le_bytes())?;
    for part in [id.as_bytes(), &stats, &fields] {
        w.write_all(&(part.len() as u32).to_le_bytes())?;
        w.write_all(part)?;
    }
    let mut buf = Vec::with_capacity(1 << 16);
    let flush = |w: &mut Hashing<_>, buf: &mut Vec<u8>, force: bool| {
        if force || buf.len() >= 1 << 16 {
            w.write_all(buf)?;
            buf.clear();
        }
        Ok::<_, io::Error>(())
    };
    for v in &result.vertices {
        for c in [v.x, v.y, v.z] {
            buf.extend_from_slice(&c.to_le_bytes());
        }
        flush(&mut w, &mut buf, false)?;
    }
    for t in &result.triangles {
        for i in t {
            buf.extend_from_slice(&i.to_le_bytes());
        }
        flush(&mut w, &mut buf, false)?;
    }
    for value in result.fields.iter().flat_map(|f| &f.values) {
        buf.extend_from_slice(&value.to_le_bytes());
        flush(&mut w, &mut buf, false)?;
    }
    if let Some(trace) = &result.trace {
        let codes = [
            METHODS.iter().position(|&m| m == trace.method),
            CRITERIA.iter().position(|&c| c == trace.criterion),
            STOPS.iter().position(|&s| s == trace.stop),
            Some(usize::from(trace.on_nodes)),
        ];
        buf.extend(codes.map(|c| c.expect("every value has a code") as u8));
        buf.push(u8::from(trace.min_angle.is_some()));
        buf.extend_from_slice(&trace.min_angle.unwrap_or(0.0).to_le_bytes());
        for n in [
            trace.base_evaluations,
            trace.worst.len() as u64,
            trace.splits.len() as u64,
            trace.estimates.len() as u64,
        ] {
            buf.extend_from_slice(&n.to_le_bytes());
        }
        for w_ in &trace.worst {
            buf.extend_from_slice(&w_.to_le_bytes());
            flush(&mut w, &mut buf, false)?;
        }
        for (s, e) in trace.splits.iter().zip(&trace.evaluations) {
            buf.extend_from_slice(&s.to_le_bytes());
            buf.extend_from_slice(&e.to_le_bytes());
            flush(&mut w, &mut buf, false)?;
        }
        for (t, e) in &trace.estimates {
            buf.extend_from_slice(&t.to_le_bytes());
            buf.extend_from_slice(&e.to_le_bytes());
            flush(&mut w, &mut buf, false)?;
        }
        for end in &trace.estimate_ends {
            buf.extend_from_slice(&end.to_le_bytes());
            flush(&mut w, &mut buf, false)?;
        }
    }
    flush(&mut w, &mut buf, true)?;
    let sum = w.hash.finalize_reset();
    w.write_all(&sum)?;
    w.flush()?;
    Ok(w.written)
}

/// The codes of a trace's method, criterion and stop reason: their index here.
const METHODS: [Method; 3] = [Method::Recursive, Method::SemiRecursive, Method::DataDependent];
const CRITERIA: [Criterion; 3] = [Criterion::Variation, Criterion::Error, Criterion::Curvature];
const STOPS: [StopReason; 5] = [
    StopReason::MaxVertices,
    StopReason::Tolerance,
    StopReason::TimeLimit,
    StopReason::Cancelled,
    StopReason::Exhausted,
];

/// Reads little-endian fields off the front of a slice.
struct Reader<'a>(&'a [u8]);

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], CompactError> {
        if self.0.len() < n {
            return Err(CompactError::Length("truncated".into()));
        }
        let (head, rest) = self.0.split_at(n);
        self.0 = rest;
        Ok(head)
    }

    fn u32(&mut self) -> Result<u32, CompactError> {
        Ok(u32::from_le_bytes(self.take(4)?.try_into().expect("4 bytes")))
    }

    fn u64(&mut self) -> Result<u64, CompactError> {
        Ok(u64::from_le_bytes(self.take(8)?.try_into().expect("8 bytes")))
    }

    fn code<T: Copy>(&mut self, values: &[T]) -> Result<T, CompactError> {
        let code = self.take(1)?[0] as usize;
        values.get(code).copied().ok_or_else(|| CompactError::Length(format!("unknown code {code}")))
    }

    /// `n` records of `size` bytes each, after checking they are there.
    fn records(&mut self, n: u64, size: usize) -> Result<std::slice::ChunksExact<'a, u8>, CompactError> {
        let bytes = usize::try_from(n).ok().and_then(|n| n.checked_mul(size));
        let bytes = bytes.ok_or_else(|| CompactError::Length(format!("{n} records do not fit")))?;
        Ok(self.take(bytes)?.chunks_exact(size))
    }
}

fn u32_at(c: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(c[at..at + 4].try_into().expect("4 bytes"))
}

fn u64_at(c: &[u8], at: usize) -> u64 {
    u64::from_le_bytes(c[at..at + 8].try_into().expect("8 bytes"))
}

fn f64_at(c: &[u8], at: usize) -> f64 {
    f64::from_bits(u64_at(c, at))
}

/// The trace section, to the end of `r`.
fn read_trace(r: &mut Reader<'_>) -> Result<Trace, CompactError> {
    let (method, criterion, stop) = (r.code(&METHODS)?, r.code(&CRITERIA)?, r.code(&STOPS)?);
    let on_nodes = r.code(&[false, true])?;
    let has_min_angle = r.code(&[false, true])?;
    let min_angle = Some(f64::from_bits(r.u64()?)).filter(|_| has_min_angle);
    let (base_evaluations, checks, steps, estimates) = (r.u64()?, r.u64()?, r.u64()?, r.u64()?);
    let worst = r.records(checks, 8)?.map(|c| f64_at(c, 0)).collect();
    let (splits, evaluations) = r.records(steps, 12)?.map(|c| (u32_at(c, 0), u64_at(c, 4))).unzip();
    let estimates = r.records(estimates, 12)?.map(|c| (u32_at(c, 0), f64_at(c, 4))).collect();
    let estimate_ends = r.records(steps.saturating_add(1), 4)?.map(|c| u32_at(c, 0)).collect();
    if !r.0.is_empty() {
        return Err(CompactError::Length(format!("{} bytes after the trace", r.0.len())));
    }
    Ok(Trace {
        method,
        criterion,
        on_nodes,
        min_angle,
        stop,
        base_evaluations,
        worst,
        splits,
        evaluations,
        estimates,
        estimate_ends,
    })
}

/// The result in `bytes`, which must be stored under `id`.
///
/// # Errors
/// When the bytes are not this format, do not add up, fail the checksum, hold another id or
/// name vertices that are not there. Sizes are checked before anything is allocated.
pub fn read(bytes: &[u8], id: &str) -> Result<RunResult, CompactError> {
    let Some(body_len) = bytes.len().checked_sub(CHECKSUM_LEN) else {
        return Err(CompactError::Format);
    };
    let (body, sum) = bytes.split_at(body_len);
    let mut r = Reader(body);
    if r.take(MAGIC.len()).ok() != Some(MAGIC.as_slice()) || r.u32()? != VERSION {
        return Err(CompactError::Format);
    }
    if Sha256::digest(body).as_slice() != sum {
        return Err(CompactError::Checksum);
    }
    let flags = r.u32()?;
    let (nv, nt) = (r.u64()?, r.u64()?);
    let stored_id = r.u32().and_then(|n| r.take(n as usize))?;
    if stored_id != id.as_bytes() {
        return Err(CompactError::Id(String::from_utf8_lossy(stored_id).into_owned()));
    }
    let stats = r.u32().and_then(|n| r.take(n as usize))?;
    let stats = serde_json::from_slice(stats).map_err(|e| CompactError::Stats(e.to_string()))?;
    let fields = r.u32().and_then(|n| r.take(n as usize))?;
    let mut fields: Vec<Field> =
        serde_json::from_slice(fields).map_err(|e| CompactError::Fields(e.to_string()))?;
    if let Some(f) = fields.iter().find(|f| f.components == 0) {
        return Err(CompactError::Fields(format!("{} has no components", f.name)));
    }
    // The numbers each field holds: its components per vertex or per triangle.
    let count = |f: &Field| match f.location {
        Location::Point => u128::from(nv) * u128::from(f.components),
        Location::Cell => u128::from(nt) * u128::from(f.components),
    };
    let values = fields.iter().map(count).sum::<u128>();
    let expected = u128::from(nv) * 24 + u128::from(nt) * 12 + values * 8;
    let fits = match flags & HAS_TRACE {
        0 => expected == r.0.len() as u128,
        _ => expected <= r.0.len() as u128,
    };
    if !fits {
        return Err(CompactError::Length(format!(
            "{nv} vertices and {nt} triangles need {expected} bytes, found {}",
            r.0.len()
        )));
    }
    let (nv, nt) = (nv as usize, nt as usize);
    let vertices: Vec<Vertex> = r
        .take(24 * nv)?
        .chunks_exact(24)
        .map(|c| Vertex { x: f64_at(c, 0), y: f64_at(c, 8), z: f64_at(c, 16) })
        .collect();
    let triangles: Vec<[u32; 3]> = r
        .take(12 * nt)?
        .chunks_exact(12)
        .map(|c| [0, 4, 8].map(|k| u32::from_le_bytes(c[k..k + 4].try_into().expect("4 bytes"))))
        .collect();
    if let Some(t) = triangles.iter().position(|t| t.iter().any(|&v| v as usize >= nv)) {
        return Err(CompactError::Triangle(t));
    }
    for field in &mut fields {
        // Fits: the sum of every count was checked against the bytes there.
        let n = count(field) as usize;
        field.values = r.take(8 * n)?.chunks_exact(8).map(|c| f64_at(c, 0)).collect();
    }
    let trace = match flags & HAS_TRACE {
        0 => None,
        _ => Some(Arc::new(read_trace(&mut r)?)),
    };
    Ok(RunResult { vertices, triangles, fields, stats, trace })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::refine::Criterion;
    use crate::result::Role;
    use crate::result::testing::sample;

    const ID: &str = "ab12";

    fn bytes(result: &RunResult) -> Vec<u8> {
        let mut out = Vec::new();
        let n = write(result, ID, &mut out).unwrap();
        assert_eq!(n, out.len() as u64);
        assert_eq!(size(result, ID), n, "size() foretells what write() writes");
        out
    }

    #[test]
    fn every_field_reads_back_equal_and_a_cut_one_is_refused() {
        let mut result = sample(300, Criterion::Error);
        let (nv, nt) = (result.vertices.len(), result.triangles.len());
        result.fields.push(Field::cell_vector(
            "H",
            "magnetic_field",
            "A/m",
            Role::Extra,
            (0..nt).map(|t| [t as f64, -(t as f64)]),
        ));
        result.fields.push(Field {
            location: Location::Point,
            ..Field::cell_scalar("s", "s", "", Role::Extra, (0..nv).map(|v| v as f64 / 7.0).collect())
        });
        let data = bytes(&result);
        assert_eq!(read(&data, ID).unwrap(), result);
        let solution = crate::result::testing::magnetic(200);
        assert_eq!(read(&bytes(&solution), ID).unwrap(), solution);
        // Without the last field's last vertex, the lengths no longer agree.
        let mut short = data[..data.len() - CHECKSUM_LEN - 8].to_vec();
        short.extend_from_slice(&Sha256::digest(&short));
        assert!(matches!(read(&short, ID), Err(CompactError::Length(_))));
    }

    #[test]
    fn a_result_reads_back_equal_with_and_without_triangle_errors() {
        for criterion in CRITERIA {
            let result = sample(300, criterion);
            assert_eq!(result.indicator().is_some(), criterion == Criterion::Error);
            assert_eq!(read(&bytes(&result), ID).unwrap(), result);
        }
    }

    #[test]
    fn a_result_with_its_trace_reads_back_equal() {
        for criterion in CRITERIA {
            let result = crate::result::testing::traced(300, criterion);
            assert!(result.trace.is_some());
            assert_eq!(read(&bytes(&result), ID).unwrap(), result);
        }
        // Every method's code reads back as that method.
        for method in METHODS {
            let mut result = crate::result::testing::traced(30, Criterion::Error);
            Arc::get_mut(result.trace.as_mut().unwrap()).unwrap().method = method;
            let back = read(&bytes(&result), ID).unwrap();
            assert_eq!(back.trace.as_ref().map(|t| t.method), Some(method));
        }
    }

    #[test]
    fn every_flipped_byte_is_refused() {
        let data = bytes(&sample(20, Criterion::Error));
        for k in 0..data.len() {
            let mut bad = data.clone();
            bad[k] ^= 0x10;
            assert!(read(&bad, ID).is_err(), "byte {k} of {} flipped and accepted", data.len());
        }
    }

    #[test]
    fn edited_stats_with_a_stale_checksum_are_refused() {
        let data = bytes(&sample(20, Criterion::Error));
        let text = String::from_utf8_lossy(&data).into_owned();
        let at = text.find("\"vertices\":20").expect("stats hold the count");
        let mut bad = data.clone();
        bad[at + 12] = b'1';
        assert_eq!(read(&bad, ID), Err(CompactError::Checksum));
    }

    #[test]
    fn a_truncated_file_or_another_id_is_refused() {
        let data = bytes(&sample(20, Criterion::Variation));
        for len in [0, 8, 40, data.len() - 33, data.len() - 1] {
            assert!(read(&data[..len], ID).is_err(), "truncated to {len}");
        }
        assert_eq!(read(&data, "cd34"), Err(CompactError::Id(ID.into())));
    }
}
