//! The built-in materials a request may name: air, conductors, electrical steels with their
//! published B–H tables, and magnet grades, each with where its figures come from.
//!
//! The data is `materials.json` beside this file, rebuilt from its sources by
//! `bench/materials.py` (the steels' tables and the NdFeB grades from pyleecan 1.4.2's
//! material files; the ferrite grade from FEMM 4.2's library).

use serde::{Deserialize, Serialize};
use std::sync::LazyLock;

/// A built-in material.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Material {
    /// The name a request gives it by (matched ignoring ASCII case).
    pub name: String,
    /// What it is: `air`, `conductor`, `steel` or `magnet`.
    pub kind: String,
    /// Relative permeability: a linear material's, or a magnet's recoil permeability.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub mu_r: Option<f64>,
    /// A steel's B–H table, [[H in A/m, B in T], …] from [0, 0].
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub bh: Option<Vec<[f64; 2]>>,
    /// A magnet's remanence in T.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub br: Option<f64>,
    /// A magnet's coercivity H_cB in A/m.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub hc: Option<f64>,
    /// Electrical conductivity in S/m (for eddy currents; magnetostatics does not read it).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub conductivity: Option<f64>,
    /// Where the figures come from.
    pub source: String,
}

static LIBRARY: LazyLock<Vec<Material>> = LazyLock::new(|| {
    serde_json::from_str(include_str!("materials.json")).expect("materials.json is a list of materials")
});

/// Every built-in material, in the library's order.
pub fn library() -> &'static [Material] {
    &LIBRARY
}

/// The built-in material called `name`, ignoring ASCII case.
pub fn find(name: &str) -> Option<&'static Material> {
    LIBRARY.iter().find(|m| m.name.eq_ignore_ascii_case(name))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solve::BhCurve;

    #[test]
    fn every_built_in_material_is_a_valid_law_with_a_source_and_a_unique_name() {
        let names: std::collections::HashSet<_> =
            library().iter().map(|m| m.name.to_ascii_lowercase()).collect();
        assert_eq!(names.len(), library().len());
        for m in library() {
            assert!(!m.source.is_empty(), "{}", m.name);
            match m.kind.as_str() {
                "steel" => {
                    let table = m.bh.as_ref().unwrap_or_else(|| panic!("{} has no table", m.name));
                    BhCurve::new(table).unwrap_or_else(|e| panic!("{}: {e}", m.name));
                }
                "magnet" => {
                    assert!(m.br.is_some_and(|b| b > 0.0), "{}", m.name);
                    assert!(m.mu_r.is_some() || m.hc.is_some(), "{}", m.name);
                }
                "air" | "conductor" => assert_eq!(m.mu_r, Some(1.0), "{}", m.name),
                other => panic!("{} is of no known kind {other}", m.name),
            }
        }
        assert_eq!(find("m400-50a").map(|m| m.bh.as_ref().map(Vec::len)), Some(Some(44)));
        assert!(find("unobtainium").is_none());
    }
}
