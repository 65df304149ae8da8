//! The layout of src/: no two files import each other in a circle, directly or through other
//! files, so that each file can be read knowing only the ones below it.
//!
//! A module with modules inside it (`mod.rs`, `lib.rs`, or `expr.rs` beside `expr/`) is their
//! facade: it declares what they share and routes to them, so it is not a file of any circle;
//! an item it re-exports counts as the file that defines it.
//!
//! An import is a path from `crate::`, `super::`, `self::` or a child module, outside
//! comments and test modules. A path that
//! names a module points at that module's file; one that names an item a `mod.rs` re-exports
//! (`pub use child::Item`) points at the child that defines it.

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

/// The module a file holds, and whether it is a directory's `mod.rs` (or `lib.rs`).
fn module_of(src: &Path, file: &Path) -> (Module, bool) {
    let rel = file.strip_prefix(src).unwrap().with_extension("");
    let mut segments: Module = rel.iter().map(|s| s.to_string_lossy().into_owned()).collect();
    let is_dir = matches!(segments.last().map(String::as_str), Some("mod" | "lib"));
    if is_dir {
        segments.pop();
    }
    (segments, is_dir)
}

/// The code of a file without comments and without its inline `mod tests { … }` block (a
/// `mod tests;` line stays: that file is skipped as a whole, see [`is_test_file`]).
fn code(text: &str) -> String {
    let text: String = text.lines().map(|l| l.split("//").next().unwrap()).collect::<Vec<_>>().join("\n");
    let Some(start) = text.find("#[cfg(test)]\nmod tests {") else { return text };
    let (mut depth, mut end) = (0usize, text.len());
    for (i, c) in text[start..].char_indices() {
        match c {
            '{' => depth += 1,
            '}' if depth == 1 => {
                end = start + i + 1;
                break;
            }
            '}' => depth -= 1,
            _ => {}
        }
    }
    format!("{}{}", &text[..start], &text[end..])
}

/// Files that only tests compile (`#[cfg(test)] mod x;` in their parent).
fn is_test_file(src: &Path, file: &Path) -> bool {
    let (module, _) = module_of(src, file);
    let Some(name) = module.last() else { return false };
    let parent = file.parent().unwrap();
    let declared_in =
        if file.file_stem().is_some_and(|s| s == "mod") { parent.parent().unwrap() } else { parent };
    [declared_in.join("mod.rs"), declared_in.with_extension("rs"), src.join("lib.rs")]
        .iter()
        .filter_map(|f| std::fs::read_to_string(f).ok())
        .any(|t| {
            t.contains(&format!("#[cfg(test)]\nmod {name};"))
                || t.contains(&format!("#[cfg(test)]\npub(super) mod {name};"))
        })
}

fn ident(s: &str) -> &str {
    let end = s.find(|c: char| !(c.is_alphanumeric() || c == '_')).unwrap_or(s.len());
    &s[..end]
}

/// Every path in `code` that starts at `crate::`, `super::`, `self::` or a child module of
/// `module` (`listen::run` in `cluster/mod.rs`), from the crate root: `a::b::{c, d::e}` gives
/// `[a, b, c]` and `[a, b, d, e]`.
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
            let (mut depth, mut item_start) = (0usize, 0);
            for (i, c) in inner.char_indices() {
                match c {
                    '{' => depth += 1,
                    '}' if depth == 0 => {
                        group(inner[item_start..i].trim(), base.clone(), found);
                        return;
                    }
                    '}' => depth -= 1,
                    ',' if depth == 0 => {
                        group(inner[item_start..i].trim(), base.clone(), found);
                        item_start = i + 1;
                    }
                    _ => {}
                }
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
    // main.rs is the binary, another crate; test-only files are not the crate's layout.
    all.retain(|f| f != &src.join("main.rs") && !is_test_file(&src, f));
    let modules: BTreeMap<Module, (PathBuf, bool)> = all
        .iter()
        .map(|f| {
            let (module, is_dir) = module_of(&src, f);
            (module, (f.clone(), is_dir))
        })
        .collect();
    // (directory module, item) → the child module that defines it, from `pub use child::…`.
    let mut reexports: BTreeMap<(Module, String), Module> = BTreeMap::new();
    for (module, (file, _)) in &modules {
        let text = code(&std::fs::read_to_string(file).unwrap());
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
    let facade = |m: &Module| modules.keys().any(|o| o.len() > m.len() && o.starts_with(m));
    for (module, (file, _)) in &modules {
        if facade(module) {
            continue;
        }
        let text = code(&std::fs::read_to_string(file).unwrap());
        let children: BTreeSet<String> = modules
            .keys()
            .filter(|m| m.len() == module.len() + 1 && m.starts_with(module))
            .map(|m| m.last().unwrap().clone())
            .collect();
        let targets = paths(&text, module, &children)
            .into_iter()
            .filter_map(|p| resolve(&p))
            .filter(|t| t != module && !facade(t));
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
