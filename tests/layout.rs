//! The layout of src/: no two files import each other in a circle, directly or through other
//! files, so that each file can be read knowing only the ones below it; and the map of the
//! crate in lib.rs's docs names exactly the arrows between its top-level modules that the code
//! has.
//!
//! A module with modules inside it (`mod.rs`, `lib.rs`, or `expr.rs` beside `expr/`) is their
//! facade, and a file like any other: its re-exports (`pub use child::…`) import its children,
//! and an item it re-exports counts, for whoever imports it through the facade, as the file
//! that defines it. So a facade that is a map (docs and re-exports) is in no circle, while one
//! that defines an item its children import is in one with them.
//!
//! An import is a path from `crate::`, `super::` or `self::` (or, in a facade, from one of its
//! child modules), outside comments and test modules. A path that names a module points at
//! that module's file.

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

/// The code of a file without comments and without its inline test modules
/// (`#[cfg(test)] mod tests { … }`, `#[cfg(test)] pub(crate) mod testing { … }`); a
/// `mod tests;` line stays: it marks a test-only file.
fn code(text: &str) -> String {
    let mut text: String = text.lines().map(|l| l.split("//").next().unwrap()).collect::<Vec<_>>().join("\n");
    const TEST: &str = "#[cfg(test)]\n";
    let mut from = 0;
    while let Some(at) = text[from..].find(TEST).map(|i| from + i) {
        let after = &text[at + TEST.len()..];
        let head_len = after.find(['{', ';']).unwrap_or(after.len());
        let is_inline_module = after[..head_len]
            .trim_start_matches("pub(crate) ")
            .trim_start_matches("pub ")
            .starts_with("mod ")
            && after[head_len..].starts_with('{');
        if !is_inline_module {
            from = at + TEST.len();
            continue;
        }
        let open = at + TEST.len() + head_len + 1;
        let end = top_level(&text[open..]).map_or(text.len(), |(_, close)| open + close + 1);
        text.replace_range(at..end, "");
        from = at;
    }
    text
}

fn ident(s: &str) -> &str {
    let end = s.find(|c: char| !(c.is_alphanumeric() || c == '_')).unwrap_or(s.len());
    &s[..end]
}

/// Every path in `code` that starts at `crate::`, `super::`, `self::` or one of the file's
/// `children`, from the crate root: `a::b::{c, d::e}` gives `[a, b, c]` and `[a, b, d, e]`.
fn paths(code: &str, module: &Module, children: &BTreeSet<String>) -> Vec<Module> {
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
            child if children.contains(child) => module.iter().cloned().chain([child.to_owned()]).collect(),
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

/// Every module of src/ but the binary's, with its code (comments and test modules out), and
/// without the test-only modules.
fn modules(src: &Path) -> BTreeMap<Module, String> {
    let mut all = Vec::new();
    files(src, &mut all);
    // src/bin/ is the binary, another crate.
    all.retain(|f| !f.starts_with(src.join("bin")));
    let mut modules: BTreeMap<Module, String> =
        all.iter().map(|f| (module_of(src, f), code(&std::fs::read_to_string(f).unwrap()))).collect();
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
    modules
}

/// Each module's imports, as the modules (files) they point at.
fn imports(modules: &BTreeMap<Module, String>) -> BTreeMap<Module, BTreeSet<Module>> {
    // Each facade's child modules, by name.
    let mut children: BTreeMap<Module, BTreeSet<String>> = BTreeMap::new();
    for module in modules.keys() {
        if let Some((name, parent)) = module.split_last() {
            children.entry(parent.to_vec()).or_default().insert(name.clone());
        }
    }
    // (facade, item) → the child module that defines it, from `pub use child::…`.
    let mut reexports: BTreeMap<(Module, String), Module> = BTreeMap::new();
    for (module, text) in modules {
        for decl in text.split("pub use ").skip(1).chain(text.split("pub(crate) use ").skip(1)) {
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
    let none = BTreeSet::new();
    let mut imports: BTreeMap<Module, BTreeSet<Module>> = BTreeMap::new();
    for (module, text) in modules {
        let kids = children.get(module).unwrap_or(&none);
        let targets =
            paths(text, module, kids).into_iter().filter_map(|p| resolve(&p)).filter(|t| t != module);
        imports.entry(module.clone()).or_default().extend(targets);
    }
    imports
}

fn src() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

#[test]
fn no_two_files_of_src_import_each_other_in_a_circle() {
    let imports = imports(&modules(&src()));
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

/// The arrows between top-level modules that the code has: `a → b` when a file under `a`
/// imports one under `b`.
fn top_level_arrows() -> BTreeSet<(String, String)> {
    let mut arrows = BTreeSet::new();
    for (from, targets) in imports(&modules(&src())) {
        for to in targets {
            if let (Some(a), Some(b)) = (from.first(), to.first())
                && a != b
            {
                arrows.insert((a.clone(), b.clone()));
            }
        }
    }
    arrows
}

/// The arrows of lib.rs's map: its lines `a ──▶ b, c` in the block under "# Layout".
fn mapped_arrows() -> BTreeSet<(String, String)> {
    let lib = std::fs::read_to_string(src().join("lib.rs")).unwrap();
    let block = lib.split("//! ```text\n").nth(1).expect("lib.rs has a ```text map");
    let block = &block[..block.find("//! ```").expect("the map's block closes")];
    let mut arrows = BTreeSet::new();
    for line in block.lines() {
        let line = line.trim_start_matches("//!").trim();
        let Some((from, to)) = line.split_once("──▶") else { continue };
        for to in to.split(',').filter(|to| to.trim() != "(nothing)") {
            arrows.insert((from.trim().to_owned(), to.trim().to_owned()));
        }
    }
    arrows
}

#[test]
fn the_map_in_lib_rs_names_every_arrow_between_top_level_modules_and_no_other() {
    let (real, mapped) = (top_level_arrows(), mapped_arrows());
    let show = |arrows: Vec<&(String, String)>| {
        arrows.iter().map(|(a, b)| format!("{a} ──▶ {b}")).collect::<Vec<_>>()
    };
    let unmapped = show(real.difference(&mapped).collect());
    let stale = show(mapped.difference(&real).collect());
    assert!(
        unmapped.is_empty() && stale.is_empty(),
        "lib.rs's map differs from the imports:\nin the code, not the map: {unmapped:?}\nin the map, not the code: {stale:?}"
    );
}

#[test]
fn the_engine_imports_nothing_of_the_service_and_results_nothing_of_the_solver() {
    // The engine's layers, lowest first; a result is data that any engine output becomes.
    let engine = ["geom", "source", "refine", "solve", "result", "output", "tiles"];
    let service = ["api", "cluster", "config", "cpu", "http", "jobs", "metrics", "telemetry", "spec"];
    let wrong: Vec<_> = top_level_arrows()
        .into_iter()
        .filter(|(a, b)| {
            (engine.contains(&a.as_str()) && service.contains(&b.as_str()))
                || (a == "result" && b == "solve")
                || (a == "output" && b == "solve")
        })
        .collect();
    assert!(wrong.is_empty(), "the engine reaches up: {wrong:?}");
}
