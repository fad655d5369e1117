//! The library's modules import each other without circles: a module
//! depends only on modules below it, so each can be read (and changed)
//! knowing only what it imports.
//!
//! The graph is built from the source text: a module depends on another
//! when it names it in a path, `crate::a::b`, `super::x`, `self::x` or a
//! child's bare name `x::y` (in `use` or anywhere else). Declaring a child
//! (`mod x;`) is not a dependency. `super` inside an inline module
//! (`mod tests { .. }`, `pub mod files { .. }`) resolves to the file's
//! module, and the inline module is part of its file's module.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// A module's path from the crate root (`[]` is the root).
type Module = Vec<String>;

#[derive(Debug, Clone, PartialEq)]
enum Tok {
    Ident(String),
    Punct(char),
    /// `::`
    Sep,
}

/// Tokens of Rust source with comments, strings and characters left out
/// (they cannot hold paths or braces that matter).
fn tokens(src: &str) -> Vec<Tok> {
    let c: Vec<char> = src.chars().collect();
    let mut out = Vec::new();
    let mut i = 0;
    while i < c.len() {
        let ch = c[i];
        if ch == '/' && c.get(i + 1) == Some(&'/') {
            while i < c.len() && c[i] != '\n' {
                i += 1;
            }
        } else if ch == '/' && c.get(i + 1) == Some(&'*') {
            let mut depth = 0;
            while i < c.len() {
                if c[i] == '/' && c.get(i + 1) == Some(&'*') {
                    depth += 1;
                    i += 2;
                } else if c[i] == '*' && c.get(i + 1) == Some(&'/') {
                    depth -= 1;
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    i += 1;
                }
            }
        } else if ch == '"' {
            i += 1;
            while i < c.len() && c[i] != '"' {
                if c[i] == '\\' {
                    i += 1;
                }
                i += 1;
            }
            i += 1;
        } else if (ch == 'r' || ch == 'b')
            && raw_string_hashes(&c, i).is_some()
            && !prev_is_ident(&c, i)
        {
            let (start, hashes) = raw_string_hashes(&c, i).unwrap();
            i = start;
            let close: Vec<char> = std::iter::once('"')
                .chain(std::iter::repeat_n('#', hashes))
                .collect();
            while i < c.len() && !c[i..].starts_with(&close) {
                i += 1;
            }
            i += close.len();
        } else if ch == '\'' {
            // A character literal or a lifetime.
            if c.get(i + 1) == Some(&'\\') {
                i += 2;
                while i < c.len() && c[i] != '\'' {
                    i += 1;
                }
                i += 1;
            } else if c.get(i + 2) == Some(&'\'') {
                i += 3;
            } else {
                i += 1;
                while i < c.len() && (c[i].is_alphanumeric() || c[i] == '_') {
                    i += 1;
                }
            }
        } else if ch.is_alphabetic() || ch == '_' {
            let s = i;
            while i < c.len() && (c[i].is_alphanumeric() || c[i] == '_') {
                i += 1;
            }
            out.push(Tok::Ident(c[s..i].iter().collect()));
        } else if ch == ':' && c.get(i + 1) == Some(&':') {
            out.push(Tok::Sep);
            i += 2;
        } else {
            if !ch.is_whitespace() {
                out.push(Tok::Punct(ch));
            }
            i += 1;
        }
    }
    out
}

fn prev_is_ident(c: &[char], i: usize) -> bool {
    i > 0 && (c[i - 1].is_alphanumeric() || c[i - 1] == '_')
}

/// At `r"`, `r#"`, `br"`..: where the text starts and how many `#`.
fn raw_string_hashes(c: &[char], i: usize) -> Option<(usize, usize)> {
    let mut j = i;
    if c[j] == 'b' {
        j += 1;
    }
    if c.get(j) != Some(&'r') {
        return None;
    }
    j += 1;
    let mut hashes = 0;
    while c.get(j) == Some(&'#') {
        hashes += 1;
        j += 1;
    }
    (c.get(j) == Some(&'"')).then_some((j + 1, hashes))
}

/// The library's source files and their modules (the `cosim` binary's
/// `main.rs` and `commands/` are another crate).
fn library_files(src: &Path) -> Vec<(PathBuf, Module)> {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        for e in std::fs::read_dir(dir).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                walk(&p, out);
            } else if p.extension().is_some_and(|x| x == "rs") {
                out.push(p);
            }
        }
    }
    let mut files = Vec::new();
    walk(src, &mut files);
    files.sort();
    files
        .into_iter()
        .filter_map(|p| {
            let rel = p.strip_prefix(src).unwrap();
            let mut parts: Vec<String> = rel
                .iter()
                .map(|s| s.to_string_lossy().trim_end_matches(".rs").to_string())
                .collect();
            if parts == ["main"] || parts[0] == "commands" {
                return None;
            }
            if matches!(parts.last().map(String::as_str), Some("lib" | "mod")) {
                parts.pop();
            }
            Some((p, parts))
        })
        .collect()
}

/// Every module (file or inline) with the children it declares.
fn declared(files: &[(PathBuf, Vec<Tok>, Module)]) -> BTreeMap<Module, BTreeSet<String>> {
    let mut children: BTreeMap<Module, BTreeSet<String>> = BTreeMap::new();
    for (_, toks, module) in files {
        children.entry(module.clone()).or_default();
        walk_modules(toks, module, |m, _| {
            children.entry(m.to_vec()).or_default();
            if let Some((last, parent)) = m.split_last() {
                children
                    .entry(parent.to_vec())
                    .or_default()
                    .insert(last.clone());
            }
        });
    }
    children
}

/// Calls `f(module, index)` for every token with the (inline) module it
/// sits in.
fn walk_modules(toks: &[Tok], file_module: &Module, mut f: impl FnMut(&[String], usize)) {
    // The inline modules open at each brace depth.
    let mut stack: Vec<(usize, String)> = Vec::new();
    let mut depth = 0usize;
    let mut pending: Option<String> = None;
    let mut current = file_module.clone();
    for (i, t) in toks.iter().enumerate() {
        match t {
            Tok::Ident(m) if m == "mod" => {
                if let Some(Tok::Ident(name)) = toks.get(i + 1) {
                    match toks.get(i + 2) {
                        Some(Tok::Punct('{')) => pending = Some(name.clone()),
                        // `mod x;`: a file module, found by its path.
                        _ => {
                            let mut m = current.clone();
                            m.push(name.clone());
                            f(&m, i);
                        }
                    }
                }
            }
            Tok::Punct('{') => {
                depth += 1;
                if let Some(name) = pending.take() {
                    stack.push((depth, name.clone()));
                    current.push(name);
                    f(&current, i);
                }
            }
            Tok::Punct('}') => {
                if stack.last().is_some_and(|(d, _)| *d == depth) {
                    stack.pop();
                    current.pop();
                }
                depth = depth.saturating_sub(1);
            }
            _ => {}
        }
        f(&current, i);
    }
}

/// The longest known module a path names, from its segments.
fn longest_module(
    base: Module,
    segs: &[String],
    modules: &BTreeMap<Module, BTreeSet<String>>,
) -> Module {
    let mut m = base;
    for s in segs {
        let mut next = m.clone();
        next.push(s.clone());
        if modules.contains_key(&next) {
            m = next;
        } else {
            break;
        }
    }
    m
}

/// An inline module is part of its file's module: the file is the unit
/// that is read and changed together.
fn fold_inline(m: &[String], file_modules: &BTreeSet<Module>) -> Module {
    (0..=m.len())
        .rev()
        .map(|n| m[..n].to_vec())
        .find(|p| file_modules.contains(p))
        .unwrap_or_default()
}

/// The paths a module names from the tokens at `i`: `a::b::c`, and for a
/// `use` tree `a::{b::c, d}` each branch.
fn paths_at(toks: &[Tok], i: usize) -> Vec<Vec<String>> {
    let mut segs = Vec::new();
    let mut j = i;
    while let Some(Tok::Ident(s)) = toks.get(j) {
        segs.push(s.clone());
        if toks.get(j + 1) != Some(&Tok::Sep) {
            return vec![segs];
        }
        j += 2;
        if toks.get(j) == Some(&Tok::Punct('{')) {
            // A use tree: each branch at depth one, prefixed.
            let mut out = Vec::new();
            let mut depth = 0;
            let mut k = j;
            let mut start = true;
            while let Some(t) = toks.get(k) {
                match t {
                    Tok::Punct('{') => {
                        depth += 1;
                        start = true;
                    }
                    Tok::Punct('}') => {
                        depth -= 1;
                        if depth == 0 {
                            break;
                        }
                    }
                    Tok::Punct(',') => start = true,
                    Tok::Ident(_) if start && depth == 1 => {
                        for rest in paths_at(toks, k) {
                            let mut p = segs.clone();
                            p.extend(rest);
                            out.push(p);
                        }
                        start = false;
                    }
                    _ => start = false,
                }
                k += 1;
            }
            return out;
        }
    }
    vec![segs]
}

/// The module dependency graph: module -> modules it names.
fn graph(src: &Path) -> BTreeMap<Module, BTreeSet<Module>> {
    let files: Vec<(PathBuf, Vec<Tok>, Module)> = library_files(src)
        .into_iter()
        .map(|(p, m)| {
            let text = std::fs::read_to_string(&p).unwrap();
            (p, tokens(&text), m)
        })
        .collect();
    let modules = declared(&files);
    let file_modules: BTreeSet<Module> = files.iter().map(|(_, _, m)| m.clone()).collect();
    let mut deps: BTreeMap<Module, BTreeSet<Module>> = BTreeMap::new();
    for (_, toks, file_module) in &files {
        deps.entry(file_module.clone()).or_default();
        let mut seen = BTreeSet::new();
        walk_modules(toks, file_module, |current, i| {
            // Each token once (walk_modules may call twice at a brace).
            if !seen.insert(i) {
                return;
            }
            // A path starts here, not in the middle of one.
            if i > 0 && toks[i - 1] == Tok::Sep {
                return;
            }
            let Tok::Ident(first) = &toks[i] else { return };
            if toks.get(i + 1) != Some(&Tok::Sep) {
                return;
            }
            // `pub(crate)`, `pub(super)` are not paths (no `::` follows).
            for path in paths_at(toks, i) {
                let mut base: Module = current.to_vec();
                let mut rest = &path[..];
                match first.as_str() {
                    "crate" => {
                        base = Vec::new();
                        rest = &path[1..];
                    }
                    "self" => rest = &path[1..],
                    "super" => {
                        while rest.first().is_some_and(|s| s == "super") {
                            base.pop();
                            rest = &rest[1..];
                        }
                    }
                    name if modules.get(current).is_some_and(|c| c.contains(name)) => {}
                    _ => continue,
                }
                let target = fold_inline(&longest_module(base, rest, &modules), &file_modules);
                let from = fold_inline(current, &file_modules);
                if target != from {
                    deps.entry(from).or_default().insert(target);
                }
            }
        });
    }
    deps
}

fn name(m: &Module) -> String {
    if m.is_empty() {
        "crate".into()
    } else {
        m.join("::")
    }
}

/// The shortest cycle through each module that is on one (Tarjan's
/// strongly connected components, then breadth first in each).
fn cycles(deps: &BTreeMap<Module, BTreeSet<Module>>) -> Vec<Vec<Module>> {
    struct State<'a> {
        deps: &'a BTreeMap<Module, BTreeSet<Module>>,
        index: BTreeMap<&'a Module, usize>,
        low: BTreeMap<&'a Module, usize>,
        stack: Vec<&'a Module>,
        on: BTreeSet<&'a Module>,
        sccs: Vec<Vec<&'a Module>>,
    }
    fn visit<'a>(s: &mut State<'a>, v: &'a Module) {
        let n = s.index.len();
        s.index.insert(v, n);
        s.low.insert(v, n);
        s.stack.push(v);
        s.on.insert(v);
        for w in s.deps.get(v).into_iter().flatten() {
            let Some((w, _)) = s.deps.get_key_value(w) else {
                continue;
            };
            if !s.index.contains_key(w) {
                visit(s, w);
                let l = s.low[w].min(s.low[v]);
                s.low.insert(v, l);
            } else if s.on.contains(w) {
                let l = s.index[w].min(s.low[v]);
                s.low.insert(v, l);
            }
        }
        if s.low[v] == s.index[v] {
            let mut scc = Vec::new();
            while let Some(w) = s.stack.pop() {
                s.on.remove(w);
                scc.push(w);
                if w == v {
                    break;
                }
            }
            s.sccs.push(scc);
        }
    }
    let mut s = State {
        deps,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on: BTreeSet::new(),
        sccs: Vec::new(),
    };
    for v in deps.keys() {
        if !s.index.contains_key(v) {
            visit(&mut s, v);
        }
    }
    let mut out = Vec::new();
    for scc in s.sccs.into_iter().filter(|c| c.len() > 1) {
        let members: BTreeSet<&Module> = scc.iter().copied().collect();
        // The shortest cycle through each member, each cycle once.
        let mut found: BTreeSet<Vec<Module>> = BTreeSet::new();
        for &start in &members {
            let mut cycle = shortest_cycle(deps, &members, start);
            // Rotated to start at its least module, to be named once.
            cycle.pop();
            let least = (0..cycle.len()).min_by_key(|&i| &cycle[i]).unwrap();
            cycle.rotate_left(least);
            cycle.push(cycle[0].clone());
            found.insert(cycle);
        }
        out.extend(found);
    }
    out
}

/// Breadth first from `start` back to `start`, inside the component.
fn shortest_cycle(
    deps: &BTreeMap<Module, BTreeSet<Module>>,
    members: &BTreeSet<&Module>,
    start: &Module,
) -> Vec<Module> {
    let mut prev: BTreeMap<&Module, &Module> = BTreeMap::new();
    let mut queue = std::collections::VecDeque::from([start]);
    let mut end = None;
    'search: while let Some(v) = queue.pop_front() {
        for w in &deps[v] {
            if w == start {
                end = Some(v);
                break 'search;
            }
            if let Some((w, _)) = deps.get_key_value(w) {
                if members.contains(w) && !prev.contains_key(w) {
                    prev.insert(w, v);
                    queue.push_back(w);
                }
            }
        }
    }
    let mut cycle = vec![start.clone()];
    let mut v = end.expect("a component's member is on a cycle");
    while v != start {
        cycle.push(v.clone());
        v = prev[v];
    }
    cycle.push(start.clone());
    let n = cycle.len();
    cycle[1..n - 1].reverse();
    cycle
}

#[test]
fn the_library_modules_import_each_other_without_circles() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let deps = graph(&src);
    // The graph is read at all: the launcher depends on the scenario files.
    assert!(deps[&vec!["launch".to_string()]].contains(&vec!["scenario".to_string()]));
    let found = cycles(&deps);
    let text: Vec<String> = found
        .iter()
        .map(|c| c.iter().map(name).collect::<Vec<_>>().join(" -> "))
        .collect();
    assert!(
        found.is_empty(),
        "modules import each other in circles:\n{}",
        text.join("\n")
    );
}

#[test]
fn a_circle_is_found_and_named() {
    let deps: BTreeMap<Module, BTreeSet<Module>> = [
        (vec!["a".into()], [vec!["b".into()]].into()),
        (vec!["b".into()], [vec!["c".into()]].into()),
        (vec!["c".into()], [vec!["a".into()], vec![]].into()),
        (vec![], BTreeSet::new()),
    ]
    .into();
    let found = cycles(&deps);
    assert_eq!(found.len(), 1);
    let names: Vec<String> = found[0].iter().map(name).collect();
    assert_eq!(names, ["a", "b", "c", "a"]);
}

#[test]
fn use_trees_and_super_resolve_to_modules() {
    let toks = tokens("use super::{a::{b, c::D}, e};\n// crate::x\nlet s = \"crate::y\";");
    let paths = paths_at(&toks, 1);
    assert_eq!(
        paths,
        [
            vec!["super", "a", "b"],
            vec!["super", "a", "c", "D"],
            vec!["super", "e"]
        ]
    );
    assert!(!toks.contains(&Tok::Ident("x".into())));
    assert!(!toks.contains(&Tok::Ident("y".into())));
}
