//! The layout of src/: no two files import each other in a circle, directly or through other
//! files, so that each file can be read knowing only the ones below it.
//!
//! A module with modules inside it (`mod.rs`, `lib.rs`, or `expr.rs` beside `expr/`) is their
//! facade: it declares what they share and routes to them, so it is not a file of any circle;
//! an item it re-exports counts as the file that defines it.
//!
//! An import is a path from `crate::`, `super::` or `self::`, outside comments and test
//! modules. A path that names a module points at that module's file.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// A module's path from the crate root, as segments (`["jobs", "peers"]`).
type Module = Vec<String>;

fn files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The module a file holds (`mod.rs` and `lib.rs` hold their directory's).
fn module_of(src: &Path, file: &Path) -> Module {
    let rel = file.strip_prefix(src).unwrap().with_extension("");
    let mut segments: Module = rel.iter().map(|s| s.to_string_lossy().into_owned()).collect();
    if matches!(segments.last().map(String::as_str), Some("mod" | "lib")) {
        segments.pop();
    }
    segments
}

/// The items of a `{…}` group at its top level, and where the group closes; `inner` starts
/// after the `{`. None when it never closes.
fn top_level(inner: &str) -> Option<(Vec<&str>, usize)> {
    let (mut depth, mut start, mut items) = (0usize, 0, Vec::new());
    for (i, c) in inner.char_indices() {
        match c {
            '{' => depth += 1,
            '}' if depth == 0 => {
                items.push(inner[start..i].trim());
                return Some((items, i));
            }
            '}' => depth -= 1,
            ',' if depth == 0 => {
                items.push(inner[start..i].trim());
                start = i + 1;
            }
            _ => {}
        }
    }
    None
}

/// The code of a file without comments and without its inline `mod tests { … }` block (a
/// `mod tests;` line stays: it marks a test-only file).
fn code(text: &str) -> String {
    let text: String = text.lines().map(|l| l.split("//").next().unwrap()).collect::<Vec<_>>().join("\n");
    const TESTS: &str = "#[cfg(test)]\nmod tests {";
    let Some(start) = text.find(TESTS) else { return text };
    let end = top_level(&text[start + TESTS.len()..])
        .map_or(text.len(), |(_, close)| start + TESTS.len() + close + 1);
    format!("{}{}", &text[..start], &text[end..])
}

fn ident(s: &str) -> &str {
    let end = s.find(|c: char| !(c.is_alphanumeric() || c == '_')).unwrap_or(s.len());
    &s[..end]
}

/// Every path in `code`, a file without child modules, that starts at `crate::`, `super::` or
/// `self::`, from the crate root: `a::b::{c, d::e}` gives `[a, b, c]` and `[a, b, d, e]`.
fn paths(code: &str, module: &Module) -> Vec<Module> {
    let mut found = Vec::new();
    for (at, _) in code.match_indices("::") {
        let head_start = code[..at].rfind(|c: char| !(c.is_alphanumeric() || c == '_')).map_or(0, |i| i + 1);
        // Only the first segment of a path: `a::b::c` is read once, from `a`.
        if code[..head_start].ends_with("::") {
            continue;
        }
        let head = &code[head_start..at];
        let mut base = match head {
            "crate" => Vec::new(),
            // `super` from a file module is its parent; from a mod.rs, the directory's parent.
            "super" => module[..module.len().saturating_sub(1)].to_vec(),
            "self" => module.clone(),
            _ => continue,
        };
        let mut rest = &code[at + 2..];
        while let Some(tail) = rest.strip_prefix("super::") {
            base.pop();
            rest = tail;
        }
        group(rest, base, &mut found);
    }
    found
}

/// The paths of `rest`, which follows `base::`: a name, a `::`-path, or a `{…}` group that
/// may nest.
fn group(mut rest: &str, mut base: Module, found: &mut Vec<Module>) {
    loop {
        if let Some(inner) = rest.strip_prefix('{') {
            for item in top_level(inner).map(|(items, _)| items).unwrap_or_default() {
                group(item, base.clone(), found);
            }
            return;
        }
        let name = ident(rest);
        if name.is_empty() {
            found.push(base);
            return;
        }
        base.push(name.to_owned());
        rest = &rest[name.len()..];
        match rest.strip_prefix("::") {
            Some(tail) => rest = tail,
            None => {
                found.push(base);
                return;
            }
        }
    }
}

#[test]
fn no_two_files_of_src_import_each_other_in_a_circle() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut all = Vec::new();
    files(&src, &mut all);
    // main.rs is the binary, another crate.
    all.retain(|f| f != &src.join("main.rs"));
    // Each module's code, read once.
    let mut modules: BTreeMap<Module, String> =
        all.iter().map(|f| (module_of(&src, f), code(&std::fs::read_to_string(f).unwrap()))).collect();
    // Test-only modules (`#[cfg(test)] mod x;` in their parent) are not the crate's layout.
    let test_only: Vec<Module> = modules
        .keys()
        .filter(|m| {
            m.split_last().is_some_and(|(name, parent)| {
                modules.get(parent).is_some_and(|text| {
                    text.contains(&format!("#[cfg(test)]\nmod {name};"))
                        || text.contains(&format!("#[cfg(test)]\npub(super) mod {name};"))
                })
            })
        })
        .cloned()
        .collect();
    for module in &test_only {
        modules.remove(module);
    }
    // The modules with modules inside them.
    let facades: BTreeSet<Module> =
        modules.keys().filter_map(|m| m.split_last()).map(|(_, parent)| parent.to_vec()).collect();
    // (facade, item) → the child module that defines it, from `pub use child::…`.
    let mut reexports: BTreeMap<(Module, String), Module> = BTreeMap::new();
    for (module, text) in &modules {
        for decl in text.split("pub use ").skip(1) {
            let decl = &decl[..decl.find(';').unwrap_or(decl.len())];
            let (child, items) = decl.split_once("::").unwrap_or((decl, ""));
            let child: Module = module.iter().cloned().chain([child.to_owned()]).collect();
            if !modules.contains_key(&child) {
                continue;
            }
            for item in items.trim_matches(|c| c == '{' || c == '}').split(',') {
                let name = item.rsplit(" as ").next().unwrap().rsplit("::").next().unwrap().trim();
                reexports.insert((module.clone(), name.to_owned()), child.clone());
            }
        }
    }
    let resolve = |path: &Module| -> Option<Module> {
        (1..=path.len()).rev().find_map(|n| {
            let prefix = path[..n].to_vec();
            if !modules.contains_key(&prefix) {
                return None;
            }
            let next = path.get(n).cloned().unwrap_or_default();
            Some(reexports.get(&(prefix.clone(), next)).cloned().unwrap_or(prefix))
        })
    };
    let mut imports: BTreeMap<Module, BTreeSet<Module>> = BTreeMap::new();
    for (module, text) in modules.iter().filter(|(m, _)| !facades.contains(*m)) {
        let targets = paths(text, module)
            .into_iter()
            .filter_map(|p| resolve(&p))
            .filter(|t| t != module && !facades.contains(t));
        imports.entry(module.clone()).or_default().extend(targets);
    }
    // A file that reaches itself through its imports is in a circle.
    let mut circles = Vec::new();
    for start in imports.keys() {
        let (mut seen, mut stack) = (BTreeSet::new(), vec![(start.clone(), vec![start.join("/")])]);
        'search: while let Some((at, trail)) = stack.pop() {
            for next in imports.get(&at).into_iter().flatten() {
                let mut trail = trail.clone();
                trail.push(next.join("/"));
                if next == start {
                    circles.push(trail.join(" → "));
                    break 'search;
                }
                if seen.insert(next.clone()) {
                    stack.push((next.clone(), trail));
                }
            }
        }
    }
    assert!(circles.is_empty(), "src/ imports in circles:\n{}", circles.join("\n"));
}
