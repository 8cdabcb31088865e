//! The rules of `ARCHITECTURE.md`, checked.
//!
//! Reads every `.rs` file under `src/`, finds what each one imports from the
//! crate (`use crate::…`, `use super::…`, `use self::…`, a declared child
//! module's path, inline `crate::`/`super::` paths, and `radbake::…` in the
//! binary's files), resolves each path to the file that defines the item
//! (following named `pub use` re-exports), and checks the file graph:
//!
//! - no import cycle between files;
//! - each file imports only its own layer or layers below it ([`LAYERS`]);
//! - `anyhow` only in the binary (`src/main.rs`, `src/cli/`);
//! - clap, indicatif, ctrlc, tokio and hyper only where the `cli` feature
//!   builds them;
//! - the meter (`trace/measure.rs`) imports no atlas, texel, validity or
//!   light-transport code.
//!
//! It also checks that the README, `ARCHITECTURE.md`, `CONTRIBUTING.md` and
//! `docs/` read as a reference (no work-journal wording) and that their
//! relative links resolve.
//!
//! `mutated_cycle_is_caught` shows the cycle check fails when a cycle is put
//! back: it adds one import to a copy of the graph.

use std::collections::{BTreeMap, BTreeSet};
use std::fs;
use std::path::{Path, PathBuf};

/// The layers, lowest first. A file belongs to the first entry whose prefix
/// its path (relative to `src/`) starts with. A file may import files of its
/// own layer (without a cycle) and of any layer listed before its own.
const LAYERS: &[(&str, &[&str])] = &[
    ("base", &["error.rs", "progress.rs", "config.rs"]),
    ("util", &["util/"]),
    ("scene", &["scene/"]),
    ("layout", &["layout/"]),
    ("raycast", &["raycast/"]),
    ("surface", &["surface/"]),
    ("light", &["light/"]),
    ("radiosity", &["radiosity/"]),
    ("maps", &["maps/"]),
    ("probes", &["probes/"]),
    ("sdf", &["sdf/"]),
    ("trace", &["trace/"]),
    ("pipeline", &["pipeline/"]),
    ("output", &["output/"]),
    ("preview", &["preview/"]),
    ("root", &["lib.rs"]),
    ("cli", &["main.rs", "cli/"]),
];

/// Files that may name the command-line-only crates.
const CLI_ONLY: &[&str] = &["main.rs", "cli/"];
const CLI_CRATES: &[&str] = &["anyhow", "clap", "indicatif", "ctrlc", "tokio", "hyper"];
/// The interactive viewer (feature `preview`) reports its errors with
/// `anyhow` too; no other library file does.
const ANYHOW_TOO: &[&str] = &["preview/"];

fn src_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

fn layer_of(rel: &str) -> Option<usize> {
    LAYERS.iter().position(|(_, prefixes)| {
        prefixes
            .iter()
            .any(|p| rel == *p || (p.ends_with('/') && rel.starts_with(p)))
    })
}

// ---------------------------------------------------------------------------
// Source text: comments and literals blanked, so only code is read.

/// `text` with comments, string and char literals replaced by spaces (line
/// breaks kept, so positions and line numbers stay).
fn code_only(text: &str) -> String {
    let b = text.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    let blank = |out: &mut Vec<u8>, c: u8| out.push(if c == b'\n' { b'\n' } else { b' ' });
    while i < b.len() {
        let c = b[i];
        if c == b'/' && b.get(i + 1) == Some(&b'/') {
            while i < b.len() && b[i] != b'\n' {
                out.push(b' ');
                i += 1;
            }
        } else if c == b'/' && b.get(i + 1) == Some(&b'*') {
            let mut depth = 0;
            while i < b.len() {
                if b[i] == b'/' && b.get(i + 1) == Some(&b'*') {
                    depth += 1;
                    out.extend_from_slice(b"  ");
                    i += 2;
                } else if b[i] == b'*' && b.get(i + 1) == Some(&b'/') {
                    depth -= 1;
                    out.extend_from_slice(b"  ");
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    blank(&mut out, b[i]);
                    i += 1;
                }
            }
        } else if c == b'r'
            && (b.get(i + 1) == Some(&b'"') || b.get(i + 1) == Some(&b'#'))
            && !ident_before(b, i)
        {
            // Raw string r"…" or r#"…"#.
            let mut j = i + 1;
            let mut hashes = 0;
            while b.get(j) == Some(&b'#') {
                hashes += 1;
                j += 1;
            }
            if b.get(j) != Some(&b'"') {
                out.push(c);
                i += 1;
                continue;
            }
            j += 1;
            loop {
                if j >= b.len() {
                    break;
                }
                if b[j] == b'"' && (0..hashes).all(|k| b.get(j + 1 + k) == Some(&b'#')) {
                    j += 1 + hashes;
                    break;
                }
                j += 1;
            }
            for &x in &b[i..j.min(b.len())] {
                blank(&mut out, x);
            }
            i = j;
        } else if c == b'"' {
            out.push(b' ');
            i += 1;
            while i < b.len() && b[i] != b'"' {
                if b[i] == b'\\' {
                    blank(&mut out, b[i]);
                    i += 1;
                }
                if i < b.len() {
                    blank(&mut out, b[i]);
                    i += 1;
                }
            }
            out.push(b' ');
            i += 1;
        } else if c == b'\'' {
            // A char literal ('x', '\n', '\u{..}'), not a lifetime.
            let end = if b.get(i + 1) == Some(&b'\\') {
                b[i + 2..]
                    .iter()
                    .position(|&x| x == b'\'')
                    .map(|p| i + 2 + p)
            } else if b.get(i + 2) == Some(&b'\'') {
                Some(i + 2)
            } else {
                None
            };
            match end {
                Some(e) => {
                    out.extend(std::iter::repeat_n(b' ', e + 1 - i));
                    i = e + 1;
                }
                None => {
                    out.push(c);
                    i += 1;
                }
            }
        } else {
            out.push(c);
            i += 1;
        }
    }
    String::from_utf8(out).expect("blanking keeps ASCII structure")
}

fn ident_before(b: &[u8], i: usize) -> bool {
    i > 0 && (b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'_')
}

#[derive(Debug, Clone, PartialEq)]
enum Tok {
    Ident(String),
    Punct(char),
    PathSep,
}

fn tokens(code: &str) -> Vec<(Tok, usize)> {
    let b = code.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    let mut line = 1;
    while i < b.len() {
        let c = b[i];
        if c == b'\n' {
            line += 1;
            i += 1;
        } else if c.is_ascii_whitespace() {
            i += 1;
        } else if c.is_ascii_alphabetic() || c == b'_' {
            let s = i;
            while i < b.len() && (b[i].is_ascii_alphanumeric() || b[i] == b'_') {
                i += 1;
            }
            out.push((Tok::Ident(code[s..i].to_string()), line));
        } else if c.is_ascii_digit() {
            while i < b.len() && (b[i].is_ascii_alphanumeric() || b[i] == b'_' || b[i] == b'.') {
                if b[i] == b'.' && b.get(i + 1) == Some(&b'.') {
                    break;
                }
                i += 1;
            }
        } else if c == b':' && b.get(i + 1) == Some(&b':') {
            out.push((Tok::PathSep, line));
            i += 2;
        } else {
            out.push((Tok::Punct(c as char), line));
            i += 1;
        }
    }
    out
}

// ---------------------------------------------------------------------------
// Files, modules and the paths they import.

/// One source file: its path relative to `src/`, the module path it is (in
/// its crate), and what it names.
#[derive(Debug)]
struct SourceFile {
    rel: String,
    /// `lib` or `bin`.
    krate: &'static str,
    module: Vec<String>,
    /// Absolute paths (from the crate root) this file names, with the line.
    paths: Vec<(Vec<String>, usize, &'static str)>,
    /// `pub use` re-exports: exported name → absolute path.
    reexports: BTreeMap<String, Vec<String>>,
    /// External crates named at the start of a path.
    externs: BTreeSet<String>,
}

fn module_of(rel: &str) -> (&'static str, Vec<String>) {
    let krate = if rel == "main.rs" || rel.starts_with("cli/") {
        "bin"
    } else {
        "lib"
    };
    let stem = rel.trim_end_matches(".rs");
    let mut parts: Vec<String> = stem.split('/').map(str::to_string).collect();
    if matches!(
        parts.last().map(String::as_str),
        Some("mod" | "lib" | "main")
    ) {
        parts.pop();
    }
    (krate, parts)
}

/// A `use` tree flattened into paths (each ending with the imported name, or
/// `*`, or `self`).
fn flatten_use(
    toks: &[(Tok, usize)],
    mut i: usize,
    prefix: Vec<String>,
    out: &mut Vec<Vec<String>>,
) -> usize {
    let mut path = prefix;
    loop {
        match toks.get(i).map(|t| &t.0) {
            Some(Tok::Ident(s)) if s == "as" => {
                i += 2; // `as name`
            }
            Some(Tok::Ident(s)) => {
                path.push(s.clone());
                i += 1;
            }
            Some(Tok::PathSep) => i += 1,
            Some(Tok::Punct('*')) => {
                path.push("*".into());
                i += 1;
            }
            Some(Tok::Punct('{')) => {
                i += 1;
                loop {
                    i = flatten_use(toks, i, path.clone(), out);
                    match toks.get(i).map(|t| &t.0) {
                        Some(Tok::Punct(',')) => i += 1,
                        Some(Tok::Punct('}')) => {
                            i += 1;
                            break;
                        }
                        _ => break,
                    }
                    if toks.get(i).map(|t| &t.0) == Some(&Tok::Punct('}')) {
                        i += 1;
                        break;
                    }
                }
                return i;
            }
            _ => {
                if !path.is_empty() {
                    out.push(path);
                }
                return i;
            }
        }
    }
}

fn parse(rel: &str, text: &str) -> SourceFile {
    let (krate, module) = module_of(rel);
    let code = code_only(text);
    let toks = tokens(&code);
    let mut file = SourceFile {
        rel: rel.to_string(),
        krate,
        module: module.clone(),
        paths: Vec::new(),
        reexports: BTreeMap::new(),
        externs: BTreeSet::new(),
    };
    // Child modules declared here (`mod x;`), and inline modules' nesting.
    let mut children: BTreeSet<String> = BTreeSet::new();
    for w in toks.windows(3) {
        if let (Tok::Ident(m), Tok::Ident(name), Tok::Punct(';')) = (&w[0].0, &w[1].0, &w[2].0) {
            if m == "mod" {
                children.insert(name.clone());
            }
        }
    }
    // Inline `mod name {` blocks: (brace depth at open, name).
    let mut inline: Vec<(usize, String)> = Vec::new();
    let mut depth = 0usize;
    let mut i = 0;
    while i < toks.len() {
        let (tok, line) = (&toks[i].0, toks[i].1);
        match tok {
            Tok::Punct('{') => {
                depth += 1;
                i += 1;
                continue;
            }
            Tok::Punct('}') => {
                depth = depth.saturating_sub(1);
                if inline.last().is_some_and(|(d, _)| *d == depth) {
                    inline.pop();
                }
                i += 1;
                continue;
            }
            _ => {}
        }
        let here: Vec<String> = module
            .iter()
            .cloned()
            .chain(inline.iter().map(|(_, n)| n.clone()))
            .collect();
        if let (Tok::Ident(m), Some((Tok::Ident(name), _)), Some((Tok::Punct('{'), _))) =
            (tok, toks.get(i + 1), toks.get(i + 2))
        {
            if m == "mod" {
                inline.push((depth, name.clone()));
                depth += 1;
                i += 3;
                continue;
            }
        }
        if let Tok::Ident(kw) = tok {
            // `#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]`: a
            // crate named only behind a feature (`command_line_crates_are_optional`
            // checks that those crates come only with the `cli` feature).
            if kw == "cfg_attr"
                && toks.get(i + 1).map(|t| &t.0) == Some(&Tok::Punct('('))
                && matches!(toks.get(i + 2).map(|t| &t.0), Some(Tok::Ident(f)) if f == "feature")
            {
                let mut open = 0usize;
                let mut j = i + 1;
                while j < toks.len() {
                    match toks[j].0 {
                        Tok::Punct('(') => open += 1,
                        Tok::Punct(')') => {
                            open -= 1;
                            if open == 0 {
                                break;
                            }
                        }
                        _ => {}
                    }
                    j += 1;
                }
                i = j + 1;
                continue;
            }
            if kw == "use" {
                let public = i > 0 && matches!(&toks[i - 1].0, Tok::Ident(p) if p == "pub")
                    || i > 3
                        && matches!(&toks[i - 1].0, Tok::Punct(')'))
                        && matches!(&toks[i - 4].0, Tok::Ident(p) if p == "pub");
                let mut flat = Vec::new();
                let leading = toks.get(i + 1).map(|t| &t.0) == Some(&Tok::PathSep);
                let end = flatten_use(&toks, i + 1 + leading as usize, Vec::new(), &mut flat);
                for p in flat {
                    let local_child = inline.is_empty() && children.contains(&p[0]);
                    let Some(abs) = absolute(&p, &here, krate, local_child) else {
                        if !leading || p[0] != "crate" {
                            file.externs.insert(p[0].clone());
                        }
                        continue;
                    };
                    if public {
                        let name = p.last().cloned().unwrap_or_default();
                        file.reexports.insert(name, abs.clone());
                    }
                    file.paths
                        .push((abs, line, if public { "re-export" } else { "use" }));
                }
                i = end;
                continue;
            }
            // An inline path: `crate::a::b`, `super::a`, `radbake::a` (bin).
            let starts = matches!(kw.as_str(), "crate" | "super")
                || (krate == "bin" && kw == "radbake")
                || (inline.is_empty() && children.contains(kw));
            let prev_sep = i > 0 && toks[i - 1].0 == Tok::PathSep;
            if starts && !prev_sep && toks.get(i + 1).map(|t| &t.0) == Some(&Tok::PathSep) {
                let mut p = vec![kw.clone()];
                let mut j = i + 1;
                while toks.get(j).map(|t| &t.0) == Some(&Tok::PathSep) {
                    match toks.get(j + 1).map(|t| &t.0) {
                        Some(Tok::Ident(s)) => {
                            p.push(s.clone());
                            j += 2;
                        }
                        _ => break,
                    }
                }
                if let Some(abs) = absolute(&p, &here, krate, children.contains(kw)) {
                    file.paths.push((abs, line, "path"));
                }
                i = j;
                continue;
            }
            // An external crate named in code (`anyhow::`, `clap::`…).
            if !prev_sep
                && toks.get(i + 1).map(|t| &t.0) == Some(&Tok::PathSep)
                && CLI_CRATES.contains(&kw.as_str())
            {
                file.externs.insert(kw.clone());
            }
            // `#[derive(clap::…)]`, `#[command]` and friends are caught by the
            // crate name above; `#[derive(ValueEnum)]` needs a `use clap::`.
        }
        i += 1;
    }
    file
}

/// A path as written → an absolute one: `("lib"|"bin", segments…)`. `None`
/// for an external crate.
fn absolute(p: &[String], here: &[String], krate: &str, local_child: bool) -> Option<Vec<String>> {
    let mut out: Vec<String>;
    let mut rest = p;
    match p[0].as_str() {
        "crate" => {
            out = vec![krate.to_string()];
            rest = &p[1..];
        }
        "radbake" if krate == "bin" => {
            out = vec!["lib".to_string()];
            rest = &p[1..];
        }
        "self" => {
            out = std::iter::once(krate.to_string())
                .chain(here.iter().cloned())
                .collect();
            rest = &p[1..];
        }
        "super" => {
            out = std::iter::once(krate.to_string())
                .chain(here.iter().cloned())
                .collect();
            while rest.first().map(String::as_str) == Some("super") {
                out.pop();
                rest = &rest[1..];
            }
        }
        _ if local_child => {
            out = std::iter::once(krate.to_string())
                .chain(here.iter().cloned())
                .collect();
        }
        _ => return None,
    }
    out.extend(rest.iter().filter(|s| *s != "self").cloned());
    Some(out)
}

// ---------------------------------------------------------------------------
// The file graph.

struct Graph {
    files: Vec<SourceFile>,
    /// (crate, module path) → file index.
    by_module: BTreeMap<(String, Vec<String>), usize>,
    /// file → (file, line, how) it imports.
    edges: BTreeMap<usize, BTreeMap<usize, (usize, &'static str)>>,
}

impl Graph {
    fn load(src: &Path) -> Graph {
        let mut rels = Vec::new();
        walk(src, src, &mut rels);
        rels.sort();
        let files: Vec<SourceFile> = rels
            .iter()
            .map(|rel| {
                parse(
                    rel,
                    &fs::read_to_string(src.join(rel)).expect("read a source file"),
                )
            })
            .collect();
        Graph::build(files)
    }

    fn build(files: Vec<SourceFile>) -> Graph {
        let by_module = files
            .iter()
            .enumerate()
            .map(|(i, f)| ((f.krate.to_string(), f.module.clone()), i))
            .collect();
        let mut g = Graph {
            files,
            by_module,
            edges: BTreeMap::new(),
        };
        for i in 0..g.files.len() {
            for k in 0..g.files[i].paths.len() {
                let (path, line, how) = g.files[i].paths[k].clone();
                if how == "re-export" {
                    // A re-export forwards a name; it is not a use of it.
                    continue;
                }
                if let Some(t) = g.resolve(&path, 0) {
                    if t != i {
                        g.edges
                            .entry(i)
                            .or_default()
                            .entry(t)
                            .or_insert((line, how));
                    }
                }
            }
        }
        g
    }

    /// The file that defines what `path` (absolute) names: the deepest module
    /// file on the path, then through that file's named re-exports.
    fn resolve(&self, path: &[String], hops: usize) -> Option<usize> {
        let krate = path[0].clone();
        let mut best = None;
        let mut depth = 0;
        for n in 0..path.len() {
            if let Some(&f) = self.by_module.get(&(
                krate.clone(),
                path[1..=n.max(1).min(path.len() - 1)].to_vec(),
            )) {
                if n >= 1 {
                    best = Some(f);
                    depth = n;
                }
            }
        }
        if path.len() == 1 || best.is_none() {
            best = self.by_module.get(&(krate.clone(), Vec::new())).copied();
            depth = 0;
        }
        let f = best?;
        // The next segment after the module: an item, maybe re-exported.
        if let Some(name) = path.get(depth + 1) {
            if hops < 8 {
                if let Some(target) = self.files[f].reexports.get(name) {
                    let mut next = target.clone();
                    next.extend(path[depth + 2..].iter().cloned());
                    if let Some(t) = self.resolve(&next, hops + 1) {
                        return Some(t);
                    }
                }
            }
        }
        Some(f)
    }

    fn name(&self, i: usize) -> &str {
        &self.files[i].rel
    }

    /// Strongly connected components with more than one file (Tarjan).
    fn cycles(&self) -> Vec<Vec<usize>> {
        struct T<'a> {
            g: &'a Graph,
            index: Vec<Option<usize>>,
            low: Vec<usize>,
            on: Vec<bool>,
            stack: Vec<usize>,
            next: usize,
            out: Vec<Vec<usize>>,
        }
        fn visit(t: &mut T, v: usize) {
            t.index[v] = Some(t.next);
            t.low[v] = t.next;
            t.next += 1;
            t.stack.push(v);
            t.on[v] = true;
            let succ: Vec<usize> =
                t.g.edges
                    .get(&v)
                    .map(|m| m.keys().copied().collect())
                    .unwrap_or_default();
            for w in succ {
                match t.index[w] {
                    None => {
                        visit(t, w);
                        t.low[v] = t.low[v].min(t.low[w]);
                    }
                    Some(iw) if t.on[w] => t.low[v] = t.low[v].min(iw),
                    _ => {}
                }
            }
            if Some(t.low[v]) == t.index[v] {
                let mut comp = Vec::new();
                while let Some(w) = t.stack.pop() {
                    t.on[w] = false;
                    comp.push(w);
                    if w == v {
                        break;
                    }
                }
                if comp.len() > 1 {
                    comp.sort();
                    t.out.push(comp);
                }
            }
        }
        let n = self.files.len();
        let mut t = T {
            g: self,
            index: vec![None; n],
            low: vec![0; n],
            on: vec![false; n],
            stack: Vec::new(),
            next: 0,
            out: Vec::new(),
        };
        for v in 0..n {
            if t.index[v].is_none() {
                visit(&mut t, v);
            }
        }
        t.out
    }

    fn cycle_report(&self) -> Vec<String> {
        self.cycles()
            .iter()
            .map(|c| {
                let set: BTreeSet<usize> = c.iter().copied().collect();
                let inner: Vec<String> = c
                    .iter()
                    .flat_map(|&a| {
                        self.edges[&a].iter().filter(|(b, _)| set.contains(b)).map(
                            move |(&b, &(line, _))| {
                                format!("{}:{} → {}", self.name(a), line, self.name(b))
                            },
                        )
                    })
                    .collect();
                format!("cycle of {} files: {}", c.len(), inner.join(", "))
            })
            .collect()
    }

    fn layer_violations(&self) -> Vec<String> {
        let mut out = Vec::new();
        for (&a, targets) in &self.edges {
            let la = layer_of(self.name(a));
            for (&b, &(line, _)) in targets {
                let lb = layer_of(self.name(b));
                match (la, lb) {
                    (Some(x), Some(y)) if y > x => out.push(format!(
                        "{}:{} ({}) imports {} ({})",
                        self.name(a),
                        line,
                        LAYERS[x].0,
                        self.name(b),
                        LAYERS[y].0
                    )),
                    _ => {}
                }
            }
        }
        out
    }
}

fn walk(root: &Path, dir: &Path, out: &mut Vec<String>) {
    for e in fs::read_dir(dir).expect("read src/") {
        let p = e.expect("a directory entry").path();
        if p.is_dir() {
            walk(root, &p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(
                p.strip_prefix(root)
                    .unwrap()
                    .to_string_lossy()
                    .replace('\\', "/"),
            );
        }
    }
}

// ---------------------------------------------------------------------------
// The rules.

#[test]
fn every_file_has_a_layer() {
    let g = Graph::load(&src_dir());
    let missing: Vec<&str> = (0..g.files.len())
        .map(|i| g.name(i))
        .filter(|r| layer_of(r).is_none())
        .collect();
    assert!(
        missing.is_empty(),
        "files in no layer of LAYERS (add them to ARCHITECTURE.md and LAYERS): {missing:?}"
    );
}

#[test]
fn no_import_cycles() {
    let g = Graph::load(&src_dir());
    let report = g.cycle_report();
    assert!(
        report.is_empty(),
        "import cycles between files:\n{}",
        report.join("\n")
    );
}

#[test]
fn imports_follow_the_layer_order() {
    let g = Graph::load(&src_dir());
    let bad = g.layer_violations();
    assert!(
        bad.is_empty(),
        "imports against the layer order (see ARCHITECTURE.md):\n{}",
        bad.join("\n")
    );
}

#[test]
fn command_line_crates_only_in_the_binary() {
    let g = Graph::load(&src_dir());
    let mut bad = Vec::new();
    for f in &g.files {
        let cli = CLI_ONLY
            .iter()
            .any(|p| f.rel == *p || (p.ends_with('/') && f.rel.starts_with(p)));
        let viewer = ANYHOW_TOO.iter().any(|p| f.rel.starts_with(p));
        for c in CLI_CRATES {
            let allowed = cli || (viewer && *c == "anyhow");
            if !allowed && f.externs.contains(*c) {
                bad.push(format!("{} uses {c}", f.rel));
            }
        }
    }
    assert!(
        bad.is_empty(),
        "command-line crates outside src/main.rs and src/cli/:\n{}",
        bad.join("\n")
    );
}

/// Every random-stream purpose comes from the one table,
/// `util::sampling::purpose` (whose test keeps the numbers unique): no
/// file sets a purpose constant to a number of its own.
#[test]
fn stream_purposes_come_from_the_table() {
    let mut bad = Vec::new();
    let mut rels = Vec::new();
    walk(&src_dir(), &src_dir(), &mut rels);
    for rel in rels {
        if rel == "util/sampling.rs" {
            continue;
        }
        let text = fs::read_to_string(src_dir().join(&rel)).unwrap_or_default();
        for (n, line) in text.lines().enumerate() {
            let l = line.trim();
            if l.contains("const ")
                && l.contains("PURPOSE")
                && l.contains(": u64 =")
                && !l.contains("purpose::")
            {
                bad.push(format!("src/{rel}:{}: {l}", n + 1));
            }
        }
    }
    assert!(
        bad.is_empty(),
        "purposes outside util::sampling::purpose:\n{}",
        bad.join("\n")
    );
}

/// The command-line crates are optional dependencies that only the `cli`
/// feature (and, for `anyhow`, `preview`) brings, so a build tool that
/// depends on `radbake` with `default-features = false` compiles none of
/// them.
#[test]
fn command_line_crates_are_optional() {
    let toml = fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("Cargo.toml"))
        .expect("Cargo.toml");
    let deps = section(&toml, "[dependencies]");
    let features = section(&toml, "[features]");
    let mut bad = Vec::new();
    for c in CLI_CRATES {
        let line = deps
            .lines()
            .find(|l| l.starts_with(&format!("{c} ")) || l.starts_with(&format!("{c}=")));
        match line {
            Some(l) if l.contains("optional = true") => {}
            Some(l) => bad.push(format!("{c} is not optional: {l}")),
            None => bad.push(format!("{c} is not in [dependencies]")),
        }
        let dep = format!("\"dep:{c}\"");
        for f in features.lines().filter(|l| l.contains(" = [")) {
            let name = f.split(" = ").next().unwrap_or("").trim();
            let brought = f.contains(&dep);
            if brought && name != "cli" && !(name == "preview" && *c == "anyhow") {
                bad.push(format!("feature {name} brings {c}"));
            }
        }
    }
    assert!(bad.is_empty(), "{}", bad.join("\n"));
}

/// The text of a Cargo.toml section, up to the next `[` header.
fn section<'a>(toml: &'a str, header: &str) -> &'a str {
    let Some(start) = toml.find(&format!("\n{header}\n")) else {
        return "";
    };
    let body = &toml[start + header.len() + 2..];
    &body[..body.find("\n[").map_or(body.len(), |e| e + 1)]
}

#[test]
fn the_meter_shares_no_bake_code() {
    let g = Graph::load(&src_dir());
    let Some(m) = (0..g.files.len()).find(|&i| g.name(i) == "trace/measure.rs") else {
        panic!("trace/measure.rs (the meter) not found");
    };
    // Everything the meter reaches, directly or not.
    let mut seen = BTreeSet::from([m]);
    let mut todo = vec![m];
    while let Some(v) = todo.pop() {
        for &w in g
            .edges
            .get(&v)
            .map(|e| e.keys().collect::<Vec<_>>())
            .unwrap_or_default()
        {
            if seen.insert(w) {
                todo.push(w);
            }
        }
    }
    // The meter shares the scene, the world triangles, the ray caster and
    // the light-sampling library with the path tracer it runs on; it must
    // not reach the texels, patches, burial, surfaces or any light stage.
    let forbidden = [
        "layout/texels.rs",
        "layout/patches.rs",
        "layout/burial.rs",
        "surface/",
        "light/direct.rs",
        "radiosity/",
        "maps/",
        "probes/",
        "pipeline/",
    ];
    let bad: Vec<&str> = seen
        .iter()
        .map(|&i| g.name(i))
        .filter(|r| forbidden.iter().any(|p| r.starts_with(p)))
        .collect();
    assert!(bad.is_empty(), "the meter reaches bake code: {bad:?}");
}

/// The check is not blind: one import that closes a loop between two files
/// that already depend on each other one way makes `cycles` report it.
#[test]
fn mutated_cycle_is_caught() {
    let g = Graph::load(&src_dir());
    assert!(g.cycles().is_empty(), "the real tree has a cycle already");
    // Any existing edge a → b, reversed by adding b → a.
    let (&a, targets) = g
        .edges
        .iter()
        .find(|(_, t)| !t.is_empty())
        .expect("some import");
    let &b = targets.keys().next().unwrap();
    let mut files = Graph::load(&src_dir()).files;
    let target = files[a].module.clone();
    let krate = files[a].krate.to_string();
    files[b]
        .paths
        .push((std::iter::once(krate).chain(target).collect(), 1, "use"));
    let mutated = Graph::build(files);
    let report = mutated.cycle_report();
    assert_eq!(report.len(), 1, "{report:?}");
    assert!(
        report[0].contains(g.name(a)) && report[0].contains(g.name(b)),
        "{report:?}"
    );
}

/// The parser reads the forms the rules depend on.
#[test]
fn parser_reads_use_trees_and_inline_paths() {
    let f = parse(
        "light/direct.rs",
        "//! crate::layout::nothing in a comment\nuse crate::{a::{b, c as d}, e::*};\nuse super::x::Y;\nfn f() { let s = \"crate::not::this\"; crate::g::h(); }\nmod tests { use super::*; }\n",
    );
    let paths: Vec<String> = f.paths.iter().map(|(p, _, _)| p.join("::")).collect();
    assert_eq!(
        paths,
        [
            "lib::a::b",
            "lib::a::c",
            "lib::e::*",
            "lib::light::x::Y",
            "lib::g::h",
            "lib::light::direct::*"
        ]
    );
}

// ---------------------------------------------------------------------------
// The documents.

fn docs() -> Vec<PathBuf> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut out: Vec<PathBuf> = ["README.md", "ARCHITECTURE.md", "CONTRIBUTING.md"]
        .iter()
        .map(|f| root.join(f))
        .collect();
    for e in fs::read_dir(root.join("docs")).expect("docs/") {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "md") {
            out.push(p);
        }
    }
    out.sort();
    out
}

/// GitHub's heading anchors: lower case, spaces → '-', punctuation dropped.
fn anchor(heading: &str) -> String {
    heading
        .trim()
        .to_lowercase()
        .chars()
        .filter_map(|c| match c {
            ' ' => Some('-'),
            '-' | '_' => Some(c),
            c if c.is_alphanumeric() => Some(c),
            _ => None,
        })
        .collect()
}

fn anchors(text: &str) -> BTreeSet<String> {
    let mut out = BTreeSet::new();
    let mut counts: BTreeMap<String, usize> = BTreeMap::new();
    let mut fence = false;
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            fence = !fence;
        }
        if fence {
            continue;
        }
        if let Some(h) = line.strip_prefix('#') {
            let h = h.trim_start_matches('#');
            let a = anchor(&h.replace('`', ""));
            let n = counts.entry(a.clone()).or_default();
            out.insert(if *n == 0 {
                a.clone()
            } else {
                format!("{a}-{n}")
            });
            *n += 1;
        }
    }
    out
}

/// The `(target)` of every `[text](target)` outside code.
fn links(text: &str) -> Vec<(usize, String)> {
    let mut out = Vec::new();
    let mut fence = false;
    for (n, line) in text.lines().enumerate() {
        if line.trim_start().starts_with("```") {
            fence = !fence;
        }
        if fence {
            continue;
        }
        // Drop inline code spans.
        let mut plain = String::new();
        let mut code = false;
        for c in line.chars() {
            if c == '`' {
                code = !code;
            } else if !code {
                plain.push(c);
            }
        }
        let mut rest = plain.as_str();
        while let Some(p) = rest.find("](") {
            let after = &rest[p + 2..];
            if let Some(e) = after.find(')') {
                out.push((n + 1, after[..e].trim().to_string()));
                rest = &after[e..];
            } else {
                break;
            }
        }
    }
    out
}

#[test]
fn relative_links_resolve() {
    let mut bad = Vec::new();
    for doc in docs() {
        let Ok(text) = fs::read_to_string(&doc) else {
            bad.push(format!("{} is missing", doc.display()));
            continue;
        };
        for (line, target) in links(&text) {
            if target.contains("://") || target.starts_with("mailto:") {
                continue;
            }
            let (file, frag) = match target.split_once('#') {
                Some((f, a)) => (f, Some(a)),
                None => (target.as_str(), None),
            };
            let path = if file.is_empty() {
                doc.clone()
            } else {
                doc.parent().unwrap().join(file)
            };
            if !path.exists() {
                bad.push(format!("{}:{line}: {target}: no such file", doc.display()));
                continue;
            }
            if let Some(a) = frag {
                if path.extension().is_some_and(|x| x == "md") {
                    let text = fs::read_to_string(&path).unwrap();
                    if !anchors(&text).contains(a) {
                        bad.push(format!(
                            "{}:{line}: {target}: no heading #{a}",
                            doc.display()
                        ));
                    }
                }
            }
        }
    }
    assert!(bad.is_empty(), "broken links:\n{}", bad.join("\n"));
}

#[test]
fn the_readme_is_a_front_door() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let n = fs::read_to_string(root.join("README.md"))
        .unwrap()
        .lines()
        .count();
    assert!(
        n <= 400,
        "README.md has {n} lines (at most 400: move the rest to docs/)"
    );
}

/// Reference wording, not a journal: no "stop N", no words about how the
/// work was organised, no benchmarking command that is not in the repository.
#[test]
fn no_journal_wording() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut files = docs();
    for dir in ["src", "tests", "examples", "tools"] {
        let mut rels = Vec::new();
        if root.join(dir).is_dir() {
            walk(&root.join(dir), &root.join(dir), &mut rels);
        }
        files.extend(rels.into_iter().map(|r| root.join(dir).join(r)));
    }
    let words = [
        concat!("farm", "-bench"),
        concat!("sess", "ion"),
        "subagent",
        "helper agent",
        "lent machine",
        "device tool",
    ];
    let mut bad = Vec::new();
    for f in files {
        if f.ends_with("tests/architecture.rs") {
            continue;
        }
        let text = fs::read_to_string(&f).unwrap_or_default();
        for (n, line) in text.lines().enumerate() {
            let low = line.to_lowercase();
            if journal_stop(&low) || words.iter().any(|w| low.contains(w)) {
                bad.push(format!("{}:{}: {}", f.display(), n + 1, line.trim()));
            }
        }
    }
    assert!(bad.is_empty(), "journal wording:\n{}", bad.join("\n"));
}

/// The word "stop" followed by a number (with or without an "s", a space
/// or a hyphen between): a work period, not a product fact.
fn journal_stop(low: &str) -> bool {
    let b = low.as_bytes();
    let mut from = 0;
    while let Some(p) = low[from..].find("stop") {
        let s = from + p;
        from = s + 4;
        if s > 0 && b[s - 1].is_ascii_alphabetic() {
            continue;
        }
        let mut j = s + 4;
        if b.get(j) == Some(&b's') {
            j += 1;
        }
        if matches!(b.get(j), Some(b' ' | b'-')) && b.get(j + 1).is_some_and(|c| c.is_ascii_digit())
        {
            return true;
        }
    }
    false
}

/// `cargo test --test architecture -- --ignored --nocapture print_graph`:
/// the file graph, a line per import, for reading.
#[test]
#[ignore]
fn print_graph() {
    let g = Graph::load(&src_dir());
    for (&a, t) in &g.edges {
        for (&b, &(line, how)) in t {
            println!("{}:{line} {how} → {}", g.name(a), g.name(b));
        }
    }
    for c in g.cycle_report() {
        println!("{c}");
    }
    for v in g.layer_violations() {
        println!("layer: {v}");
    }
}
