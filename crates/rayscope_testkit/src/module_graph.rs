//! A crate's module graph from its sources: which file refers to which module, and a cycle in
//! it if there is one.
//!
//! Reads `src/**/*.rs`, resolves every `use crate::…`, `use super::…`, `use self::…`, `crate::x::…`
//! path in code and path through a child module declared in the file to the file that defines the
//! module. A re-export (`pub use`, `pub(crate) use`) is an alias, not a use: a path through it
//! counts as a reference to the module defining the item, and the re-exporting module depends on
//! that module only where its own code names the item too. The crate root (`lib.rs`, `main.rs`)
//! is the facade and no node. Code in `#[cfg(test)]` modules (inline or in their own files) is
//! left out, since tests may look at any module. Self-contained (std only) so the check cannot
//! depend on the code it checks.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// One reference from a file to a module: the target file's module path and the line it is on.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord)]
pub struct Edge {
    /// The referring file's module path.
    pub from: String,
    /// The module referred to.
    pub to: String,
    /// The line of the reference.
    pub line: usize,
}

/// A token of Rust source with its line: identifiers, `::` and single punctuation characters.
#[derive(Debug, Clone, PartialEq)]
enum Tok {
    Ident(String),
    PathSep,
    Punct(char),
}

/// Tokens of `src` with comments, strings and character literals removed.
fn tokenize(src: &str) -> Vec<(Tok, usize)> {
    let b: Vec<char> = src.chars().collect();
    let mut out = Vec::new();
    let mut i = 0;
    let mut line = 1;
    while i < b.len() {
        let c = b[i];
        if c == '\n' {
            line += 1;
            i += 1;
        } else if c.is_whitespace() {
            i += 1;
        } else if c == '/' && b.get(i + 1) == Some(&'/') {
            while i < b.len() && b[i] != '\n' {
                i += 1;
            }
        } else if c == '/' && b.get(i + 1) == Some(&'*') {
            let mut depth = 0;
            while i < b.len() {
                if b[i] == '/' && b.get(i + 1) == Some(&'*') {
                    depth += 1;
                    i += 2;
                } else if b[i] == '*' && b.get(i + 1) == Some(&'/') {
                    depth -= 1;
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    if b[i] == '\n' {
                        line += 1;
                    }
                    i += 1;
                }
            }
        } else if c == 'r' && (b.get(i + 1) == Some(&'"') || (b.get(i + 1) == Some(&'#') && raw_string_at(&b, i))) {
            // Raw string r"…" or r#"…"#.
            i += 1;
            let mut hashes = 0;
            while b[i] == '#' {
                hashes += 1;
                i += 1;
            }
            i += 1;
            loop {
                if i >= b.len() {
                    break;
                }
                if b[i] == '\n' {
                    line += 1;
                }
                if b[i] == '"' && (0..hashes).all(|k| b.get(i + 1 + k) == Some(&'#')) {
                    i += 1 + hashes;
                    break;
                }
                i += 1;
            }
        } else if c == '"' {
            i += 1;
            while i < b.len() && b[i] != '"' {
                if b[i] == '\\' {
                    i += 1;
                }
                if i < b.len() && b[i] == '\n' {
                    line += 1;
                }
                i += 1;
            }
            i += 1;
        } else if c == '\'' {
            // A character literal ('x', '\n', '\u{..}') or a lifetime ('a).
            if b.get(i + 1) == Some(&'\\') {
                i += 2;
                while i < b.len() && b[i] != '\'' {
                    i += 1;
                }
                i += 1;
            } else if b.get(i + 2) == Some(&'\'') {
                i += 3;
            } else {
                i += 1;
                while i < b.len() && (b[i].is_alphanumeric() || b[i] == '_') {
                    i += 1;
                }
            }
        } else if c.is_alphanumeric() || c == '_' {
            let start = i;
            while i < b.len() && (b[i].is_alphanumeric() || b[i] == '_') {
                i += 1;
            }
            let word: String = b[start..i].iter().collect();
            // Byte strings and byte characters: b"…", b'…'.
            if word == "b" && i < b.len() && (b[i] == '"' || b[i] == '\'') {
                continue;
            }
            if !word.chars().next().is_some_and(|c| c.is_ascii_digit()) {
                out.push((Tok::Ident(word), line));
            }
        } else if c == ':' && b.get(i + 1) == Some(&':') {
            out.push((Tok::PathSep, line));
            i += 2;
        } else {
            out.push((Tok::Punct(c), line));
            i += 1;
        }
    }
    out
}

/// Whether `r` at `i` opens a raw string `r#…#"` (rather than a raw identifier `r#name`).
fn raw_string_at(b: &[char], i: usize) -> bool {
    let mut j = i + 1;
    while j < b.len() && b[j] == '#' {
        j += 1;
    }
    b.get(j) == Some(&'"')
}

/// The module path of a source file relative to `src/`: `lib.rs` or `main.rs` → ``, `a/b.rs` →
/// `a::b`.
pub fn module_of(rel: &str) -> String {
    let rel = rel.trim_end_matches(".rs");
    let rel = rel.strip_suffix("/mod").unwrap_or(rel);
    if rel == "lib" || rel == "main" {
        String::new()
    } else {
        rel.replace('/', "::")
    }
}

fn join(base: &[String], rest: &[String]) -> Vec<String> {
    base.iter().chain(rest).cloned().collect()
}

/// What one file declares and references, before resolution.
struct Parsed {
    /// Inline (non-test) modules declared in the file, as absolute paths.
    inline_modules: Vec<Vec<String>>,
    /// Child modules declared `mod x;` (or inline), by the module they are declared in.
    children: Vec<(Vec<String>, String)>,
    /// `pub use` items: (module, exported name, absolute target path, line).
    reexports: Vec<(Vec<String>, String, Vec<String>, usize)>,
    /// References: (absolute path, line).
    refs: Vec<(Vec<String>, usize)>,
    /// Test modules declared `#[cfg(test)] mod x;`, as absolute paths.
    test_children: Vec<Vec<String>>,
    /// How often each identifier occurs in the file's code outside test modules.
    idents: BTreeMap<String, usize>,
    /// Bare paths `x::…` (x possibly a child module) with the module they are written in.
    bare: Vec<(Vec<String>, Vec<String>, usize)>,
}

/// Makes `path` (as written in module `here`) absolute when it starts with `crate`, `super` or
/// `self`; `None` for any other first segment.
fn absolute(here: &[String], path: &[String]) -> Option<Vec<String>> {
    match path.first().map(String::as_str) {
        Some("crate") => Some(path[1..].to_vec()),
        Some("self") => Some(join(here, &path[1..])),
        Some("super") => {
            let mut base = here.to_vec();
            let mut k = 0;
            while path.get(k).map(String::as_str) == Some("super") {
                base.pop()?;
                k += 1;
            }
            Some(join(&base, &path[k..]))
        }
        _ => None,
    }
}

/// Reads a path `a::b::c` at `toks[*i]`, advancing past it.
fn read_path(toks: &[(Tok, usize)], i: &mut usize) -> Vec<String> {
    let mut segs = Vec::new();
    while let Some((Tok::Ident(w), _)) = toks.get(*i) {
        segs.push(w.clone());
        *i += 1;
        if toks.get(*i).map(|t| &t.0) == Some(&Tok::PathSep) {
            *i += 1;
        } else {
            break;
        }
    }
    segs
}

/// Reads a use tree at `toks[*i]` with `prefix` already read, pushing each leaf's full path.
fn read_use_tree(toks: &[(Tok, usize)], i: &mut usize, prefix: Vec<String>, leaves: &mut Vec<(Vec<String>, String)>) {
    let segs = read_path(toks, i);
    let path = join(&prefix, &segs);
    match toks.get(*i).map(|t| &t.0) {
        Some(Tok::Punct('{')) => {
            *i += 1;
            loop {
                match toks.get(*i).map(|t| &t.0) {
                    Some(Tok::Punct('}')) | None => {
                        *i += 1;
                        break;
                    }
                    Some(Tok::Punct(',')) => *i += 1,
                    _ => read_use_tree(toks, i, path.clone(), leaves),
                }
            }
        }
        Some(Tok::Punct('*')) => {
            *i += 1;
            leaves.push((path, "*".into()));
        }
        _ => {
            let mut name = path.last().cloned().unwrap_or_default();
            if let Some((Tok::Ident(w), _)) = toks.get(*i) {
                if w == "as" {
                    if let Some((Tok::Ident(alias), _)) = toks.get(*i + 1) {
                        name = alias.clone();
                    }
                    *i += 2;
                }
            }
            leaves.push((path, name));
        }
    }
}

/// Whether a path `a::…` starts at `toks[i]` (an identifier not itself after a `::`).
fn path_starts_at(toks: &[(Tok, usize)], i: usize) -> bool {
    let after_sep = i > 0 && toks[i - 1].0 == Tok::PathSep;
    !after_sep && toks.get(i + 1).map(|t| &t.0) == Some(&Tok::PathSep)
}

/// Parses one file of module `module`.
fn parse(module: &[String], src: &str) -> Parsed {
    let toks = tokenize(src);
    let mut p = Parsed {
        inline_modules: Vec::new(),
        children: Vec::new(),
        reexports: Vec::new(),
        refs: Vec::new(),
        bare: Vec::new(),
        test_children: Vec::new(),
        idents: BTreeMap::new(),
    };
    // The stack of inline modules: (module path, brace depth at which it closes).
    let mut stack: Vec<(Vec<String>, usize)> = vec![(module.to_vec(), 0)];
    let mut depth = 0usize;
    let mut cfg_test = false;
    let mut i = 0;
    while i < toks.len() {
        let here = stack.last().unwrap().0.clone();
        let (tok, line) = (&toks[i].0, toks[i].1);
        if let Tok::Ident(w) = tok {
            *p.idents.entry(w.clone()).or_default() += 1;
        }
        match tok {
            Tok::Punct('#') => {
                // An attribute: note `#[cfg(test)]`, skip the rest.
                let start = i;
                let mut d = 0;
                i += 1;
                if toks.get(i).map(|t| &t.0) == Some(&Tok::Punct('!')) {
                    i += 1;
                }
                while i < toks.len() {
                    match toks[i].0 {
                        Tok::Punct('[') => d += 1,
                        Tok::Punct(']') => {
                            d -= 1;
                            if d == 0 {
                                i += 1;
                                break;
                            }
                        }
                        _ => {}
                    }
                    i += 1;
                }
                let words: Vec<&str> = toks[start..i]
                    .iter()
                    .filter_map(|t| {
                        if let Tok::Ident(w) = &t.0 {
                            Some(w.as_str())
                        } else {
                            None
                        }
                    })
                    .collect();
                if words == ["cfg", "test"] {
                    cfg_test = true;
                }
                continue;
            }
            Tok::Punct('{') => {
                depth += 1;
                cfg_test = false;
            }
            Tok::Punct('}') => {
                if stack.len() > 1 && stack.last().unwrap().1 == depth {
                    stack.pop();
                }
                depth = depth.saturating_sub(1);
                cfg_test = false;
            }
            Tok::Punct(';') => cfg_test = false,
            Tok::Ident(w) if w == "mod" => {
                if let Some((Tok::Ident(name), _)) = toks.get(i + 1) {
                    let child = join(&here, std::slice::from_ref(name));
                    match toks.get(i + 2).map(|t| &t.0) {
                        Some(Tok::Punct('{')) if cfg_test => {
                            // Skip a test module whole.
                            let mut d = 0;
                            i += 2;
                            while i < toks.len() {
                                match toks[i].0 {
                                    Tok::Punct('{') => d += 1,
                                    Tok::Punct('}') => {
                                        d -= 1;
                                        if d == 0 {
                                            break;
                                        }
                                    }
                                    _ => {}
                                }
                                i += 1;
                            }
                            i += 1;
                            cfg_test = false;
                            continue;
                        }
                        Some(Tok::Punct('{')) => {
                            p.children.push((here.clone(), name.clone()));
                            p.inline_modules.push(child.clone());
                            depth += 1;
                            stack.push((child, depth));
                            i += 3;
                            continue;
                        }
                        _ if !cfg_test => p.children.push((here.clone(), name.clone())),
                        _ => p.test_children.push(child),
                    }
                }
            }
            Tok::Ident(w) if w == "use" => {
                let public = i > 0 && matches!(&toks[i - 1].0, Tok::Ident(v) if v == "pub")
                    || i > 3
                        && matches!(&toks[i - 1].0, Tok::Punct(')'))
                        && matches!(&toks[i - 4].0, Tok::Ident(v) if v == "pub");
                i += 1;
                let mut leaves = Vec::new();
                read_use_tree(&toks, &mut i, Vec::new(), &mut leaves);
                for (path, name) in leaves {
                    let abs = absolute(&here, &path);
                    if public {
                        let target = abs.clone().unwrap_or_else(|| join(&here, &path));
                        p.reexports.push((here.clone(), name, target, line));
                    } else if let Some(abs) = abs {
                        p.refs.push((abs, line));
                    } else {
                        p.bare.push((here.clone(), path, line));
                    }
                }
                cfg_test = false;
                continue;
            }
            Tok::Ident(w) if path_starts_at(&toks, i) => {
                let path = read_path(&toks, &mut i);
                if matches!(w.as_str(), "crate" | "super" | "self") {
                    if let Some(abs) = absolute(&here, &path) {
                        p.refs.push((abs, line));
                    }
                } else {
                    p.bare.push((here.clone(), path, line));
                }
                continue;
            }
            _ => {}
        }
        i += 1;
    }
    p
}

/// The graph of `files` (path relative to `src/`, contents): the modules (files other than
/// `lib.rs`) and the references between them, self-references left out.
pub fn graph(files: &[(String, String)]) -> (BTreeSet<String>, BTreeSet<Edge>) {
    let key = |m: &[String]| m.join("::");
    // Module path → the file module defining it.
    let mut file_of: BTreeMap<String, String> = BTreeMap::new();
    let mut parsed = Vec::new();
    for (rel, src) in files {
        let m = module_of(rel);
        let segs: Vec<String> = if m.is_empty() {
            Vec::new()
        } else {
            m.split("::").map(String::from).collect()
        };
        file_of.insert(m.clone(), m.clone());
        let p = parse(&segs, src);
        for inline in &p.inline_modules {
            file_of.insert(key(inline), m.clone());
        }
        parsed.push((m, p));
    }
    // Files of test modules, and files below them, are no part of the graph.
    let tests: Vec<String> = parsed
        .iter()
        .flat_map(|(_, p)| p.test_children.iter().map(|t| key(t)))
        .collect();
    parsed.retain(|(m, _)| !tests.iter().any(|t| m == t || m.starts_with(&format!("{t}::"))));
    let mut children: BTreeSet<(String, String)> = BTreeSet::new();
    let mut reexports: BTreeMap<(String, String), Vec<String>> = BTreeMap::new();
    for (_, p) in &parsed {
        for (parent, name) in &p.children {
            children.insert((key(parent), name.clone()));
        }
        for (module, name, target, _) in &p.reexports {
            reexports.insert((key(module), name.clone()), target.clone());
        }
    }
    // The file a path refers to: the file of its longest prefix that is a module, unless that
    // module re-exports the next segment, whose target is then followed.
    let resolve = |path: &[String]| -> Option<String> {
        let mut path = path.to_vec();
        for _ in 0..16 {
            let mut k = path.len();
            while k > 0 && !file_of.contains_key(&key(&path[..k])) {
                k -= 1;
            }
            match path
                .get(k)
                .and_then(|next| reexports.get(&(key(&path[..k]), next.clone())))
            {
                Some(target) => path = join(target, &path[k + 1..]),
                None if k > 0 => return file_of.get(&key(&path[..k])).cloned(),
                None => return None,
            }
        }
        None
    };
    let nodes: BTreeSet<String> = parsed
        .iter()
        .map(|(m, _)| m.clone())
        .filter(|m| !m.is_empty())
        .collect();
    let mut edges = BTreeSet::new();
    for (m, p) in &parsed {
        if m.is_empty() {
            continue;
        }
        let mut targets: Vec<(Option<String>, usize)> =
            p.refs.iter().map(|(path, line)| (resolve(path), *line)).collect();
        // A re-export is a use only where the file's own code names the item as well.
        for (_, name, target, line) in &p.reexports {
            if p.idents.get(name).copied().unwrap_or(0) > 1 {
                targets.push((resolve(target), *line));
            }
        }
        for (here, path, line) in &p.bare {
            if children.contains(&(key(here), path[0].clone())) {
                targets.push((resolve(&join(here, path)), *line));
            }
        }
        for (to, line) in targets {
            if let Some(to) = to {
                if to != *m && !to.is_empty() {
                    edges.insert(Edge {
                        from: m.clone(),
                        to,
                        line,
                    });
                }
            }
        }
    }
    (nodes, edges)
}

/// A cycle of `edges` as its modules in order (the first repeated at the end), if there is one.
pub fn find_cycle(nodes: &BTreeSet<String>, edges: &BTreeSet<Edge>) -> Option<Vec<String>> {
    let mut out: BTreeMap<&str, Vec<&str>> = BTreeMap::new();
    for e in edges {
        out.entry(e.from.as_str()).or_default().push(e.to.as_str());
    }
    // Depth-first search with colours: 0 unseen, 1 on the stack, 2 done.
    let mut colour: BTreeMap<&str, u8> = nodes.iter().map(|n| (n.as_str(), 0)).collect();
    for start in nodes {
        if colour[start.as_str()] != 0 {
            continue;
        }
        let mut stack: Vec<(&str, usize)> = vec![(start.as_str(), 0)];
        colour.insert(start.as_str(), 1);
        while let Some(&mut (node, ref mut next)) = stack.last_mut() {
            let succ = out.get(node).map(Vec::as_slice).unwrap_or(&[]);
            if let Some(&to) = succ.get(*next) {
                *next += 1;
                match colour.get(to).copied().unwrap_or(2) {
                    0 => {
                        colour.insert(to, 1);
                        stack.push((to, 0));
                    }
                    1 => {
                        let from = stack.iter().position(|&(n, _)| n == to).unwrap();
                        let mut cycle: Vec<String> = stack[from..].iter().map(|&(n, _)| n.to_string()).collect();
                        cycle.push(to.to_string());
                        return Some(cycle);
                    }
                    _ => {}
                }
            } else {
                colour.insert(node, 2);
                stack.pop();
            }
        }
    }
    None
}

/// Every `.rs` file under `dir`, as (path relative to `root`, contents).
pub fn read_sources(root: &Path, dir: &Path, out: &mut Vec<(String, String)>) {
    let mut entries: Vec<_> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().path()).collect();
    entries.sort();
    for path in entries {
        if path.is_dir() {
            read_sources(root, &path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            let rel = path.strip_prefix(root).unwrap().to_string_lossy().replace('\\', "/");
            out.push((rel, std::fs::read_to_string(&path).unwrap()));
        }
    }
}

/// The message naming `cycle`, with the line of each reference along it.
pub fn describe(krate: &str, cycle: &[String], edges: &BTreeSet<Edge>) -> String {
    let mut s = format!("module cycle in {krate}:\n");
    for pair in cycle.windows(2) {
        let lines: Vec<String> = edges
            .iter()
            .filter(|e| e.from == pair[0] && e.to == pair[1])
            .map(|e| e.line.to_string())
            .collect();
        s += &format!(
            "  {} -> {}  (src/{}.rs line {})\n",
            pair[0],
            pair[1],
            pair[0].replace("::", "/"),
            lines.join(", ")
        );
    }
    s
}

/// Whether module `m` is `root` or inside it.
pub fn within(m: &str, root: &str) -> bool {
    m == root || m.strip_prefix(root).is_some_and(|rest| rest.starts_with("::"))
}

/// The crate's source files under `crate_dir/src`, as (path relative to `src/`, contents).
pub fn crate_sources(crate_dir: &Path) -> Vec<(String, String)> {
    let src = crate_dir.join("src");
    let mut files = Vec::new();
    read_sources(&src, &src, &mut files);
    files
}

/// Panics naming the cycle, file and line by line, when the crate at `crate_dir` has one; also
/// when the reader found fewer than `min_edges` references (a reader that sees nothing proves
/// nothing).
pub fn assert_acyclic(krate: &str, crate_dir: &Path, min_edges: usize) {
    let files = crate_sources(crate_dir);
    let (nodes, edges) = graph(&files);
    assert!(
        edges.len() >= min_edges,
        "the graph reader found too little in {krate}: {nodes:?} {edges:?}"
    );
    if let Some(cycle) = find_cycle(&nodes, &edges) {
        panic!("{}", describe(krate, &cycle, &edges));
    }
}

/// Panics naming the cycle when the crate's top-level modules, each taken with the modules
/// inside it, refer to each other in a cycle: the layering of a crate whose modules split one
/// type's methods over child files (which refer to their parent and it to them).
pub fn assert_top_level_acyclic(krate: &str, crate_dir: &Path, min_edges: usize) {
    let files = crate_sources(crate_dir);
    let (nodes, edges) = graph(&files);
    let top = |m: &str| m.split("::").next().unwrap_or(m).to_string();
    let nodes: BTreeSet<String> = nodes.iter().map(|m| top(m)).collect();
    let edges: BTreeSet<Edge> = edges
        .iter()
        .map(|e| Edge {
            from: top(&e.from),
            to: top(&e.to),
            line: e.line,
        })
        .filter(|e| e.from != e.to)
        .collect();
    assert!(
        edges.len() >= min_edges,
        "the graph reader found too little in {krate}: {nodes:?} {edges:?}"
    );
    if let Some(cycle) = find_cycle(&nodes, &edges) {
        panic!("{}", describe(krate, &cycle, &edges));
    }
}
