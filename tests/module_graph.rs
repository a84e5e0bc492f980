//! The files of `src/` import each other without cycles.
//!
//! Every `.rs` file under `src/` is a node. An edge A → B exists when A names an item
//! path that resolves into file B: `crate::x::y::…`, `super::…` (relative to A's module,
//! or to the inline `mod m { … }` the path stands in), `self::…`, and `child::…` where
//! `child` is declared in A by `mod child;` — in `use` declarations (groups such as
//! `use crate::{a::b, c::{d, e}}` included) and in expressions and types alike. A path
//! resolves to the file of its longest prefix that is a module (`src/x/y.rs` or
//! `src/x/y/mod.rs`; `src/lib.rs` is the crate root, `src/main.rs` the root of the
//! binary's own crate). Comments and string literals are not read. A failure prints each
//! strongly connected component of more than one file with its internal edges.
//!
//! Self-contained (no dependencies); the checker is proven on in-memory examples below.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

#[derive(Clone, Debug, PartialEq)]
enum Token {
    Ident(String),
    /// `::`
    PathSep,
    Open,
    Close,
    Comma,
    Semi,
    Star,
    Other,
}

/// The tokens of `src` that matter here, with comments (`//`, `/* */`, nested), string,
/// byte-string, raw-string and char literals, and lifetimes left out.
fn tokens(src: &str) -> Vec<Token> {
    let c: Vec<char> = src.chars().collect();
    let n = c.len();
    let mut out = Vec::new();
    let mut i = 0;
    // Skips a "…" literal whose opening quote is at `i`; returns the index after it.
    let quoted = |mut i: usize| -> usize {
        i += 1;
        while i < n && c[i] != '"' {
            i += if c[i] == '\\' { 2 } else { 1 };
        }
        i + 1
    };
    // Skips r#…#"…"#…# with its first '#' or '"' at `i`; None if no '"' follows the #s.
    let raw = |mut i: usize| -> Option<usize> {
        let mut hashes = 0;
        while i < n && c[i] == '#' {
            hashes += 1;
            i += 1;
        }
        if i >= n || c[i] != '"' {
            return None;
        }
        i += 1;
        loop {
            if i >= n {
                return Some(n);
            }
            if c[i] == '"' && (1..=hashes).all(|k| i + k < n && c[i + k] == '#') {
                return Some(i + 1 + hashes);
            }
            i += 1;
        }
    };
    while i < n {
        let ch = c[i];
        if ch == '/' && i + 1 < n && c[i + 1] == '/' {
            while i < n && c[i] != '\n' {
                i += 1;
            }
        } else if ch == '/' && i + 1 < n && c[i + 1] == '*' {
            let mut depth = 0;
            while i < n {
                if c[i] == '/' && i + 1 < n && c[i + 1] == '*' {
                    depth += 1;
                    i += 2;
                } else if c[i] == '*' && i + 1 < n && c[i + 1] == '/' {
                    depth -= 1;
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    i += 1;
                }
            }
        } else if ch.is_whitespace() {
            i += 1;
        } else if ch == '"' {
            i = quoted(i);
        } else if ch == '\'' {
            // A char literal ('x', '\n', '\u{7f}') or a lifetime ('a).
            if i + 1 < n && c[i + 1] == '\\' {
                i += 2;
                while i < n && c[i] != '\'' {
                    i += 1;
                }
                i += 1;
            } else if i + 2 < n && c[i + 2] == '\'' {
                i += 3;
            } else {
                i += 1;
                while i < n && (c[i].is_alphanumeric() || c[i] == '_') {
                    i += 1;
                }
            }
        } else if ch.is_alphabetic() || ch == '_' {
            let start = i;
            while i < n && (c[i].is_alphanumeric() || c[i] == '_') {
                i += 1;
            }
            let word: String = c[start..i].iter().collect();
            let next = c.get(i).copied();
            match (word.as_str(), next) {
                ("r" | "br", Some('"' | '#')) => match raw(i) {
                    Some(end) => i = end,
                    None => i += 1, // r#ident: the identifier follows
                },
                ("b", Some('"')) => i = quoted(i),
                ("b", Some('\'')) => {} // b'x': the char literal follows
                _ => out.push(Token::Ident(word)),
            }
        } else if ch.is_ascii_digit() {
            while i < n
                && (c[i].is_alphanumeric()
                    || c[i] == '_'
                    || (c[i] == '.' && c.get(i + 1).is_some_and(char::is_ascii_digit)))
            {
                i += 1;
            }
        } else {
            out.push(match ch {
                ':' if i + 1 < n && c[i + 1] == ':' => {
                    i += 1;
                    Token::PathSep
                }
                '{' => Token::Open,
                '}' => Token::Close,
                ',' => Token::Comma,
                ';' => Token::Semi,
                '*' => Token::Star,
                _ => Token::Other,
            });
            i += 1;
        }
    }
    out
}

fn ident(t: Option<&Token>) -> Option<&str> {
    match t {
        Some(Token::Ident(s)) => Some(s),
        _ => None,
    }
}

/// The paths of the use tree starting at `t[*i]`, each prefixed by `prefix`; leaves `*i`
/// after the tree. `*` and a trailing `self` name the prefix itself; `as x` is dropped.
fn use_tree(t: &[Token], i: &mut usize, prefix: Vec<String>, out: &mut Vec<Vec<String>>) {
    let mut path = prefix;
    loop {
        match t.get(*i) {
            Some(Token::PathSep) => *i += 1, // a leading `::`
            Some(Token::Ident(s)) => {
                path.push(s.clone());
                *i += 1;
                if t.get(*i) == Some(&Token::PathSep) {
                    *i += 1;
                    continue;
                }
                if ident(t.get(*i)) == Some("as") {
                    *i += 2;
                }
                if path.len() > 1 && path.last().map(String::as_str) == Some("self") {
                    path.pop();
                }
                out.push(path);
                return;
            }
            Some(Token::Star) => {
                *i += 1;
                out.push(path);
                return;
            }
            Some(Token::Open) => {
                *i += 1;
                loop {
                    match t.get(*i) {
                        None => return,
                        Some(Token::Close) => {
                            *i += 1;
                            return;
                        }
                        Some(Token::Comma) => *i += 1,
                        _ => use_tree(t, i, path.clone(), out),
                    }
                }
            }
            _ => {
                out.push(path);
                return;
            }
        }
    }
}

/// One file's references: (the module path of the inline-module scope the path stands
/// in, relative to the file's module; the path).
struct FileRefs {
    paths: Vec<(Vec<String>, Vec<String>)>,
    /// `mod child;` declarations, by scope.
    children: BTreeMap<Vec<String>, BTreeSet<String>>,
}

fn references(src: &str) -> FileRefs {
    let t = tokens(src);
    let mut refs = FileRefs {
        paths: Vec::new(),
        children: BTreeMap::new(),
    };
    // Inline modules entered: (name, brace depth inside it).
    let mut scope: Vec<(String, usize)> = Vec::new();
    let names = |scope: &[(String, usize)]| scope.iter().map(|s| s.0.clone()).collect::<Vec<_>>();
    let mut depth = 0;
    let mut i = 0;
    while i < t.len() {
        match &t[i] {
            Token::Open => {
                depth += 1;
                i += 1;
            }
            Token::Close => {
                if scope.last().is_some_and(|s| s.1 == depth) {
                    scope.pop();
                }
                depth -= 1;
                i += 1;
            }
            Token::Ident(w) if w == "mod" && ident(t.get(i + 1)).is_some() => {
                let name = ident(t.get(i + 1)).unwrap().to_string();
                match t.get(i + 2) {
                    Some(Token::Semi) => {
                        refs.children.entry(names(&scope)).or_default().insert(name);
                        i += 3;
                    }
                    Some(Token::Open) => {
                        depth += 1;
                        scope.push((name, depth));
                        i += 3;
                    }
                    _ => i += 2,
                }
            }
            Token::Ident(w) if w == "use" => {
                i += 1;
                let mut paths = Vec::new();
                use_tree(&t, &mut i, Vec::new(), &mut paths);
                let here = names(&scope);
                refs.paths
                    .extend(paths.into_iter().map(|p| (here.clone(), p)));
            }
            Token::Ident(first)
                if (i == 0 || t[i - 1] != Token::PathSep)
                    && t.get(i + 1) == Some(&Token::PathSep)
                    && ident(t.get(i + 2)).is_some() =>
            {
                let mut path = vec![first.clone()];
                i += 1;
                while t.get(i) == Some(&Token::PathSep) {
                    match ident(t.get(i + 1)) {
                        Some(s) => path.push(s.to_string()),
                        None => break,
                    }
                    i += 2;
                }
                refs.paths.push((names(&scope), path));
            }
            _ => i += 1,
        }
    }
    refs
}

/// A file's crate (`true` for the binary, `src/main.rs`) and module path, from its path
/// relative to `src/` (with `/`).
fn module_of(rel: &str) -> (bool, Vec<String>) {
    let stem = rel.strip_suffix(".rs").unwrap_or(rel);
    let mut parts: Vec<String> = stem.split('/').map(str::to_string).collect();
    let bin = parts == ["main"];
    if matches!(
        parts.last().map(String::as_str),
        Some("mod" | "lib" | "main")
    ) {
        parts.pop();
    }
    (bin, parts)
}

/// The import graph of `files` (path relative to `src/`, text): file → files it refers to.
fn graph(files: &[(String, String)]) -> BTreeMap<String, BTreeSet<String>> {
    let modules: BTreeMap<(bool, Vec<String>), &str> = files
        .iter()
        .map(|(rel, _)| (module_of(rel), rel.as_str()))
        .collect();
    let mut edges = BTreeMap::new();
    for (rel, src) in files {
        let (bin, me) = module_of(rel);
        let refs = references(src);
        let mut to = BTreeSet::new();
        for (scope, path) in &refs.paths {
            if path.is_empty() {
                continue;
            }
            let here: Vec<String> = me.iter().chain(scope).cloned().collect();
            let absolute: Vec<String> = match path[0].as_str() {
                "crate" => path[1..].to_vec(),
                "self" => here.iter().chain(&path[1..]).cloned().collect(),
                "super" => {
                    let mut base = here.clone();
                    let mut rest = &path[..];
                    while rest.first().map(String::as_str) == Some("super") {
                        base.pop();
                        rest = &rest[1..];
                    }
                    base.into_iter().chain(rest.iter().cloned()).collect()
                }
                first if refs.children.get(scope).is_some_and(|c| c.contains(first)) => {
                    here.iter().chain(path).cloned().collect()
                }
                _ => continue,
            };
            let target = (0..=absolute.len())
                .rev()
                .find_map(|k| modules.get(&(bin, absolute[..k].to_vec())));
            if let Some(&target) = target {
                if target != rel {
                    to.insert(target.to_string());
                }
            }
        }
        edges.insert(rel.clone(), to);
    }
    edges
}

/// The strongly connected components of more than one node (Tarjan), each sorted.
fn cycles(edges: &BTreeMap<String, BTreeSet<String>>) -> Vec<Vec<String>> {
    struct Tarjan<'a> {
        edges: &'a BTreeMap<String, BTreeSet<String>>,
        index: BTreeMap<&'a str, usize>,
        low: BTreeMap<&'a str, usize>,
        stack: Vec<&'a str>,
        on_stack: BTreeSet<&'a str>,
        out: Vec<Vec<String>>,
    }
    impl<'a> Tarjan<'a> {
        fn visit(&mut self, v: &'a str) {
            let i = self.index.len();
            self.index.insert(v, i);
            self.low.insert(v, i);
            self.stack.push(v);
            self.on_stack.insert(v);
            let edges = self.edges;
            for w in edges.get(v).into_iter().flatten() {
                let w = w.as_str();
                if !self.index.contains_key(w) {
                    self.visit(w);
                    let l = self.low[v].min(self.low[w]);
                    self.low.insert(v, l);
                } else if self.on_stack.contains(w) {
                    let l = self.low[v].min(self.index[w]);
                    self.low.insert(v, l);
                }
            }
            if self.low[v] == self.index[v] {
                let mut component = Vec::new();
                loop {
                    let w = self.stack.pop().unwrap();
                    self.on_stack.remove(w);
                    component.push(w.to_string());
                    if w == v {
                        break;
                    }
                }
                if component.len() > 1 {
                    component.sort();
                    self.out.push(component);
                }
            }
        }
    }
    let mut t = Tarjan {
        edges,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on_stack: BTreeSet::new(),
        out: Vec::new(),
    };
    for v in edges.keys() {
        if !t.index.contains_key(v.as_str()) {
            t.visit(v);
        }
    }
    t.out.sort();
    t.out
}

/// Each cycle with its internal edges, as printed on failure.
fn report(edges: &BTreeMap<String, BTreeSet<String>>, cycles: &[Vec<String>]) -> String {
    let mut s = String::new();
    for c in cycles {
        s += &format!("cycle among {} files: {}\n", c.len(), c.join(", "));
        for a in c {
            let inside: Vec<&str> = edges[a]
                .iter()
                .filter(|b| c.contains(b))
                .map(String::as_str)
                .collect();
            s += &format!("    {a} -> {}\n", inside.join(", "));
        }
    }
    s
}

fn rs_files(dir: &Path, root: &Path, out: &mut Vec<(String, String)>) {
    let mut entries: Vec<_> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.unwrap().path())
        .collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            rs_files(&p, root, out);
        } else if p.extension().is_some_and(|e| e == "rs") {
            let rel = p
                .strip_prefix(root)
                .unwrap()
                .to_string_lossy()
                .replace('\\', "/");
            out.push((rel, std::fs::read_to_string(&p).unwrap()));
        }
    }
}

#[test]
fn src_files_import_each_other_without_cycles() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rs_files(&src, &src, &mut files);
    let edges = graph(&files);
    let n_edges: usize = edges.values().map(BTreeSet::len).sum();
    // Not vacuous: the files were read and refer to each other.
    assert!(
        files.len() > 1 && n_edges > 0,
        "{} files, {n_edges} edges",
        files.len()
    );
    let found = cycles(&edges);
    assert!(
        found.is_empty(),
        "{} import cycles among the {} files of src/ ({n_edges} edges):\n{}",
        found.len(),
        files.len(),
        report(&edges, &found)
    );
}

// ----- the checker on in-memory examples ------------------------------------------------

fn files(list: &[(&str, &str)]) -> Vec<(String, String)> {
    list.iter()
        .map(|(p, s)| (p.to_string(), s.to_string()))
        .collect()
}

fn edges_of(list: &[(&str, &str)]) -> BTreeMap<String, BTreeSet<String>> {
    graph(&files(list))
}

fn set(names: &[&str]) -> BTreeSet<String> {
    names.iter().map(|s| s.to_string()).collect()
}

#[test]
fn a_two_cycle_is_found_and_reported() {
    let e = edges_of(&[
        ("lib.rs", "pub mod a;\npub mod b;\n"),
        ("a.rs", "use crate::b::B;\npub struct A;\n"),
        ("b.rs", "pub struct B(crate::a::A);\n"),
    ]);
    let found = cycles(&e);
    assert_eq!(found, vec![vec!["a.rs".to_string(), "b.rs".to_string()]]);
    let r = report(&e, &found);
    assert!(
        r.contains("a.rs -> b.rs") && r.contains("b.rs -> a.rs"),
        "{r}"
    );
}

#[test]
fn a_dag_passes() {
    let e = edges_of(&[
        (
            "lib.rs",
            "pub mod a;\npub mod b;\npub mod c;\npub use a::A;\n",
        ),
        (
            "a.rs",
            "use crate::b::B;\nuse super::c;\npub struct A(B, c::C);\n",
        ),
        ("b.rs", "pub struct B(crate::c::C);\n"),
        ("c.rs", "pub struct C;\n"),
    ]);
    assert_eq!(e["lib.rs"], set(&["a.rs"]));
    assert_eq!(e["a.rs"], set(&["b.rs", "c.rs"]));
    assert_eq!(e["b.rs"], set(&["c.rs"]));
    assert!(cycles(&e).is_empty(), "{e:?}");
}

#[test]
fn use_groups_resolve_each_leaf() {
    let e = edges_of(&[
        ("lib.rs", "mod a;\nmod d;\nmod x;\nmod z;\n"),
        ("a/mod.rs", "pub mod b;\npub mod c;\n"),
        ("a/b.rs", ""),
        ("a/c.rs", ""),
        ("d.rs", "pub fn e() {}\npub fn f() {}\n"),
        (
            "z.rs",
            "pub(crate) use crate::{\n    a::{b, c::{self, Thing as Other}},\n    d::{e, f},\n};\n",
        ),
        ("x.rs", "use crate::{a::{b, c}};\n"),
    ]);
    assert_eq!(e["z.rs"], set(&["a/b.rs", "a/c.rs", "d.rs"]));
    assert_eq!(e["x.rs"], set(&["a/b.rs", "a/c.rs"]));
    // `mod` declarations alone are not references.
    assert!(e["lib.rs"].is_empty() && e["a/mod.rs"].is_empty(), "{e:?}");
}

#[test]
fn paths_resolve_to_the_longest_module_prefix() {
    let e = edges_of(&[
        ("lib.rs", "mod volume;\nmod scene;\nmod user;\n"),
        ("volume/mod.rs", "pub mod grid;\npub struct Thing;\n"),
        ("volume/grid.rs", "pub struct Grid;\n"),
        ("scene.rs", "pub mod stage;\n"),
        ("scene/stage.rs", "pub fn load() {}\n"),
        (
            "user.rs",
            "fn f() { let g = crate::volume::grid::Grid::new(); let t = crate::volume::Thing; }\n\
             fn h() { crate::scene::stage::load(); }\n",
        ),
    ]);
    assert_eq!(
        e["user.rs"],
        set(&["volume/grid.rs", "volume/mod.rs", "scene/stage.rs"])
    );
}

#[test]
fn super_self_and_declared_children_are_relative_to_the_module() {
    let e = edges_of(&[
        ("lib.rs", "pub mod track;\n"),
        (
            "track/mod.rs",
            "mod delta;\nmod ratio;\nmod spectral;\npub fn dispatch() { delta::Delta::run(); }\n\
             pub use self::ratio::Ratio;\npub struct Query;\n",
        ),
        ("track/delta.rs", "use super::Query;\npub struct Delta;\n"),
        ("track/ratio.rs", "pub struct Ratio;\n"),
        (
            "track/spectral.rs",
            "pub struct S(super::super::track::ratio::Ratio);\n",
        ),
    ]);
    assert_eq!(
        e["track/mod.rs"],
        set(&["track/delta.rs", "track/ratio.rs"])
    );
    assert_eq!(e["track/delta.rs"], set(&["track/mod.rs"]));
    assert_eq!(e["track/spectral.rs"], set(&["track/ratio.rs"]));
    assert_eq!(
        cycles(&e),
        vec![vec![
            "track/delta.rs".to_string(),
            "track/mod.rs".to_string()
        ]]
    );
}

#[test]
fn comments_and_strings_are_not_read() {
    let e = edges_of(&[
        ("lib.rs", "mod a;\nmod b;\n"),
        (
            "a.rs",
            "// use crate::b::B;\n/* crate::b::B /* nested */ crate::b::B */\n\
             const S: &str = \"crate::b::B\"; const R: &str = r#\"crate::b::{B}\"#;\n\
             const C: char = '{'; fn f<'a>(x: &'a str) {} // crate::b::B\n",
        ),
        ("b.rs", "pub struct B(crate::a::A);\n"),
    ]);
    assert!(e["a.rs"].is_empty(), "{e:?}");
    assert!(cycles(&e).is_empty());
}

#[test]
fn super_inside_an_inline_module_is_the_file_itself() {
    let e = edges_of(&[
        ("lib.rs", "mod a;\nmod b;\n"),
        (
            "a.rs",
            "pub struct A;\n#[cfg(test)]\nmod tests {\n    use super::*;\n    fn f() { let s = format!(\"{}\", 1); }\n}\n\
             fn g() { crate::b::f(); }\n",
        ),
        ("b.rs", "pub fn f() {}\nmod inner { use super::super::a::A; }\n"),
    ]);
    assert_eq!(e["a.rs"], set(&["b.rs"]));
    assert_eq!(e["b.rs"], set(&["a.rs"]));
    assert_eq!(cycles(&e).len(), 1);
}

#[test]
fn the_binary_is_its_own_crate() {
    let e = edges_of(&[
        ("lib.rs", "pub mod cli;\n"),
        ("cli.rs", "pub fn main() {}\n"),
        (
            "main.rs",
            "fn main() { nimbus::cli::main() }\nfn f() { crate::main() }\n",
        ),
    ]);
    assert!(e["main.rs"].is_empty(), "{e:?}");
}
