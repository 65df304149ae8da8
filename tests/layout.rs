//! The layout of src/: no two files import each other in a circle, directly or through other
//! files, so that each file can be read knowing only the ones below it.
//!
//! An import is a `crate::…` or `super::…` path outside comments and test modules. A path that
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

/// The code of a file without comments and without its `#[cfg(test)] mod tests` block.
fn code(text: &str) -> String {
    let text = text.split("#[cfg(test)]\nmod tests").next().unwrap();
    text.lines().map(|l| l.split("//").next().unwrap()).collect::<Vec<_>>().join("\n")
}

fn ident(s: &str) -> &str {
    let end = s.find(|c: char| !(c.is_alphanumeric() || c == '_')).unwrap_or(s.len());
    &s[..end]
}

/// Every path after `crate::` or `super::` in `code`, from the crate root: `a::b::{c, d::e}`
/// gives `[a, b, c]` and `[a, b, d]`.
fn paths(code: &str, module: &Module) -> Vec<Module> {
    let mut found = Vec::new();
    for (at, _) in code.match_indices("::") {
        let head_start = code[..at].rfind(|c: char| !(c.is_alphanumeric() || c == '_')).map_or(0, |i| i + 1);
        let head = &code[head_start..at];
        let mut base = match head {
            "crate" => Vec::new(),
            // `super` from a file module is its parent; from a mod.rs, the directory's parent.
            "super" if head_start < 2 || &code[head_start - 2..head_start] != "::" => {
                module[..module.len().saturating_sub(1)].to_vec()
            }
            _ => continue,
        };
        let mut rest = &code[at + 2..];
        while let Some(tail) = rest.strip_prefix("super::") {
            base.pop();
            rest = tail;
        }
        loop {
            if let Some(group) = rest.strip_prefix('{') {
                let inner = &group[..group.find('}').unwrap_or(group.len())];
                for item in inner.split(',').map(str::trim).filter(|i| !i.is_empty()) {
                    let mut path = base.clone();
                    path.push(ident(item).to_owned());
                    found.push(path);
                }
                break;
            }
            let name = ident(rest);
            if name.is_empty() {
                break;
            }
            base.push(name.to_owned());
            rest = &rest[name.len()..];
            match rest.strip_prefix("::") {
                Some(tail) => rest = tail,
                None => {
                    found.push(base);
                    break;
                }
            }
        }
    }
    found
}

#[test]
fn no_two_files_of_src_import_each_other_in_a_circle() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut all = Vec::new();
    files(&src, &mut all);
    // main.rs is the binary, another crate.
    all.retain(|f| f != &src.join("main.rs"));
    let modules: BTreeMap<Module, (PathBuf, bool)> = all
        .iter()
        .map(|f| {
            let (module, is_dir) = module_of(&src, f);
            (module, (f.clone(), is_dir))
        })
        .collect();
    // (directory module, item) → the child module that defines it, from `pub use child::…`.
    let mut reexports: BTreeMap<(Module, String), Module> = BTreeMap::new();
    for (module, (file, is_dir)) in &modules {
        if !is_dir {
            continue;
        }
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
    for (module, (file, _)) in &modules {
        let text = code(&std::fs::read_to_string(file).unwrap());
        let targets = paths(&text, module).into_iter().filter_map(|p| resolve(&p)).filter(|t| t != module);
        imports.entry(module.clone()).or_default().extend(targets);
    }
    // A file that reaches itself through its imports is in a circle.
    for start in imports.keys() {
        let (mut seen, mut stack) = (BTreeSet::new(), vec![(start.clone(), vec![start.join("/")])]);
        while let Some((at, trail)) = stack.pop() {
            for next in imports.get(&at).into_iter().flatten() {
                let mut trail = trail.clone();
                trail.push(next.join("/"));
                assert!(next != start, "src/ imports in a circle: {}", trail.join(" → "));
                if seen.insert(next.clone()) {
                    stack.push((next.clone(), trail));
                }
            }
        }
    }
}
