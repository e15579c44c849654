//! The core's module structure: the file-level import graph of `src` has no
//! circle of more than two files, and nothing in `collision` imports from
//! `world` or `solver`.
//!
//! An edge `a → b` means file `a` names a path that resolves to file `b`:
//! a `use` declaration (nested groups, `self`, globs and renames included),
//! a path written inline in code (`crate::…`, `$crate::…`, `super::…`,
//! `self::…`, or a child module's name), or a `crate::…` path in a comment
//! (a doc link). A path resolves to the
//! file of its longest prefix that is a module. Inline `mod name { … }`
//! blocks resolve relative paths from their own module. Test files (a name
//! with "test" in it, or under a `tests` folder) and `#[cfg(test)] mod tests`
//! blocks are left out.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// Every `.rs` file under `dir`, with its path relative to `root`.
fn sources(root: &Path, dir: &Path, out: &mut Vec<(String, String)>) {
    for entry in std::fs::read_dir(dir).expect("read the source folder") {
        let path = entry.expect("a folder entry").path();
        if path.is_dir() {
            sources(root, &path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            let rel = path
                .strip_prefix(root)
                .expect("under src")
                .to_string_lossy();
            let text = std::fs::read_to_string(&path).expect("read a source file");
            out.push((rel.replace('\\', "/"), text));
        }
    }
}

/// Whether a file holds only tests.
fn is_test_file(rel: &str) -> bool {
    let name = rel.rsplit('/').next().unwrap_or(rel);
    name.contains("test") || rel.split('/').any(|d| d == "tests")
}

/// The module path of a file: `world/mod.rs` is `world`, `lib.rs` the root.
fn module_of(rel: &str) -> Vec<String> {
    let mut parts: Vec<String> = rel
        .trim_end_matches(".rs")
        .split('/')
        .map(String::from)
        .collect();
    if matches!(parts.last().map(String::as_str), Some("mod" | "lib")) {
        parts.pop();
    }
    parts
}

/// The source with string and character literals blanked out (their bytes
/// become spaces, lengths and line breaks kept), so braces inside them do
/// not count; comments too unless `keep_comments` (doc links are paths).
fn blank_literals(src: &str, keep_comments: bool) -> String {
    let b = src.as_bytes();
    let mut out = b.to_vec();
    let mut i = 0;
    while i < b.len() {
        match b[i] {
            b'/' if b.get(i + 1) == Some(&b'/') => {
                while i < b.len() && b[i] != b'\n' {
                    if !keep_comments {
                        out[i] = b' ';
                    }
                    i += 1;
                }
            }
            b'/' if b.get(i + 1) == Some(&b'*') => {
                let mut depth = 0;
                let from = i;
                while i < b.len() {
                    if b[i] == b'/' && b.get(i + 1) == Some(&b'*') {
                        depth += 1;
                        i += 2;
                    } else if b[i] == b'*' && b.get(i + 1) == Some(&b'/') {
                        depth -= 1;
                        i += 2;
                        if depth == 0 {
                            break;
                        }
                    } else {
                        i += 1;
                    }
                }
                if !keep_comments {
                    for o in &mut out[from..i.min(b.len())] {
                        if *o != b'\n' {
                            *o = b' ';
                        }
                    }
                }
            }
            b'r' if (b.get(i + 1) == Some(&b'"') || b.get(i + 1) == Some(&b'#'))
                && (i == 0 || !(b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'_')) =>
            {
                let mut j = i + 1;
                let mut hashes = 0;
                while b.get(j) == Some(&b'#') {
                    hashes += 1;
                    j += 1;
                }
                if b.get(j) != Some(&b'"') {
                    i += 1;
                    continue;
                }
                j += 1;
                while j < b.len() {
                    if b[j] == b'"' && (0..hashes).all(|h| b.get(j + 1 + h) == Some(&b'#')) {
                        break;
                    }
                    out[j] = b' ';
                    j += 1;
                }
                i = j + 1 + hashes;
            }
            b'"' => {
                let mut j = i + 1;
                while j < b.len() && b[j] != b'"' {
                    if b[j] == b'\\' {
                        out[j] = b' ';
                        j += 1;
                    }
                    if j < b.len() && b[j] != b'\n' {
                        out[j] = b' ';
                    }
                    j += 1;
                }
                i = j + 1;
            }
            b'\'' => {
                // A character literal ('x', '\n', '\u{..}'), not a lifetime.
                let end = if b.get(i + 1) == Some(&b'\\') {
                    (i + 2..b.len().min(i + 12)).find(|&k| b[k] == b'\'')
                } else {
                    let c = src[i + 1..].chars().next().map_or(1, char::len_utf8);
                    (b.get(i + 1 + c) == Some(&b'\'')).then_some(i + 1 + c)
                };
                match end {
                    Some(e) => {
                        for o in &mut out[i + 1..e] {
                            *o = b' ';
                        }
                        i = e + 1;
                    }
                    None => i += 1,
                }
            }
            _ => i += 1,
        }
    }
    String::from_utf8(out).expect("only ASCII bytes were replaced")
}

/// The index just past the brace that closes the one at `open`, skipping
/// comments (the text has its literals blanked).
fn matching_brace(t: &[u8], open: usize) -> usize {
    let mut depth = 0;
    let mut i = open;
    while i < t.len() {
        if t[i] == b'/' && t.get(i + 1) == Some(&b'/') {
            while i < t.len() && t[i] != b'\n' {
                i += 1;
            }
            continue;
        }
        match t[i] {
            b'{' => depth += 1,
            b'}' => {
                depth -= 1;
                if depth == 0 {
                    return i + 1;
                }
            }
            _ => {}
        }
        i += 1;
    }
    t.len()
}

/// The text with its `pub(in path)` scopes blanked: a visibility names an
/// ancestor module, it imports nothing.
fn blank_visibility(t: &str) -> String {
    let mut out = t.to_string();
    let mut from = 0;
    while let Some(k) = out[from..].find("pub(in ") {
        let start = from + k;
        let end = out[start..].find(')').map_or(out.len(), |e| start + e + 1);
        blank(&mut out, start..end);
        from = end;
    }
    out
}

fn is_ident(c: u8) -> bool {
    c.is_ascii_alphanumeric() || c == b'_'
}

/// Whether `t[i..]` starts the word `w` (not inside a longer identifier).
fn word_at(t: &[u8], i: usize, w: &str) -> bool {
    t[i..].starts_with(w.as_bytes())
        && (i == 0 || !is_ident(t[i - 1]))
        && t.get(i + w.len()).is_none_or(|&c| !is_ident(c))
}

/// The inline `mod name { … }` blocks of the text: each one's whole range,
/// and its name and inside unless it is a `#[cfg(test)] mod tests`.
#[allow(clippy::type_complexity)]
fn inline_modules(
    t: &str,
) -> Vec<(
    std::ops::Range<usize>,
    Option<(String, std::ops::Range<usize>)>,
)> {
    let b = t.as_bytes();
    let mut blocks = Vec::new();
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'/' && b.get(i + 1) == Some(&b'/') {
            while i < b.len() && b[i] != b'\n' {
                i += 1;
            }
            continue;
        }
        if word_at(b, i, "mod") {
            let mut j = i + 3;
            while j < b.len() && b[j].is_ascii_whitespace() {
                j += 1;
            }
            let name_start = j;
            while j < b.len() && is_ident(b[j]) {
                j += 1;
            }
            let name = &t[name_start..j];
            while j < b.len() && b[j].is_ascii_whitespace() {
                j += 1;
            }
            if !name.is_empty() && b.get(j) == Some(&b'{') {
                let end = matching_brace(b, j);
                let before = t[..i].trim_end();
                let before = before.strip_suffix("pub").unwrap_or(before).trim_end();
                let test_only = before.ends_with("#[cfg(test)]") && name == "tests";
                let inside = (!test_only).then(|| (name.to_string(), j + 1..end - 1));
                blocks.push((i..end, inside));
                i = end;
                continue;
            }
        }
        i += 1;
    }
    blocks
}

/// Expands a `use` tree (`a::{b, c::{d, self}, e as f, g::*}`) into its
/// paths, each a list of segments.
fn use_paths(tree: &str) -> Vec<Vec<String>> {
    fn expand(prefix: &[String], tree: &str, out: &mut Vec<Vec<String>>) {
        let tree = tree.trim();
        if tree.is_empty() {
            return;
        }
        // Split at the first top-level `{`.
        if let Some(open) = tree.find('{') {
            let head: Vec<String> = tree[..open]
                .split("::")
                .map(str::trim)
                .filter(|s| !s.is_empty())
                .map(String::from)
                .collect();
            let close = tree.rfind('}').unwrap_or(tree.len());
            let inner = &tree[open + 1..close];
            let mut base = prefix.to_vec();
            base.extend(head);
            let mut depth = 0;
            let mut start = 0;
            for (k, c) in inner.char_indices() {
                match c {
                    '{' => depth += 1,
                    '}' => depth -= 1,
                    ',' if depth == 0 => {
                        expand(&base, &inner[start..k], out);
                        start = k + 1;
                    }
                    _ => {}
                }
            }
            expand(&base, &inner[start..], out);
        } else {
            let tree = tree.split(" as ").next().unwrap_or(tree).trim();
            let mut path = prefix.to_vec();
            for seg in tree.split("::").map(str::trim).filter(|s| !s.is_empty()) {
                if seg != "self" || path.is_empty() {
                    path.push(seg.to_string());
                }
            }
            out.push(path);
        }
    }
    let mut out = Vec::new();
    expand(&[], tree, &mut out);
    out
}

/// Blanks a range of the text (line breaks kept).
fn blank(t: &mut String, r: std::ops::Range<usize>) {
    let blanked: String = t.as_bytes()[r.clone()]
        .iter()
        .map(|&b| if b == b'\n' { '\n' } else { ' ' })
        .collect();
    t.replace_range(r, &blanked);
}

/// The module paths a piece of code names, relative paths resolved from
/// module `me`; `is_module` says whether a module path has a file. `code`
/// is `full` with its comments blanked (the same length): `use`
/// declarations are read from the code, inline paths from both.
fn named_paths(
    code: &str,
    full: &str,
    me: &[String],
    is_module: &dyn Fn(&[String]) -> bool,
) -> Vec<Vec<String>> {
    let mut out = Vec::new();
    let (mut code_rest, mut rest) = (code.to_string(), full.to_string());
    for (whole, inside) in inline_modules(full) {
        if let Some((name, r)) = inside {
            let mut inner = me.to_vec();
            inner.push(name);
            out.extend(named_paths(&code[r.clone()], &full[r], &inner, is_module));
        }
        blank(&mut code_rest, whole.clone());
        blank(&mut rest, whole);
    }
    let mut raw: Vec<Vec<String>> = Vec::new();
    // `use` declarations, to their `;`.
    let c = code_rest.as_bytes();
    let mut i = 0;
    while i < c.len() {
        if word_at(c, i, "use")
            && let Some(end) = code_rest[i..].find(';')
        {
            let tree = code_rest[i + 3..i + end].replace(['\n', '\r'], " ");
            raw.extend(use_paths(&tree));
            i += end;
            continue;
        }
        i += 1;
    }
    let b = rest.as_bytes();
    // Paths written inline: a run of `ident::ident::…` that does not
    // follow `::` or an identifier.
    let mut i = 0;
    while i < b.len() {
        let starts = is_ident(b[i])
            && (i == 0 || !(is_ident(b[i - 1]) || b[i - 1] == b':' || b[i - 1] == b'$'))
            || (b[i] == b'$' && rest[i..].starts_with("$crate::"));
        if !starts {
            i += 1;
            continue;
        }
        let start = if b[i] == b'$' { i + 1 } else { i };
        let mut j = start;
        let mut segs = Vec::new();
        loop {
            let s = j;
            while j < b.len() && is_ident(b[j]) {
                j += 1;
            }
            if s == j {
                break;
            }
            segs.push(rest[s..j].to_string());
            if rest[j..].starts_with("::") && b.get(j + 2).is_some_and(|&c| is_ident(c)) {
                j += 2;
            } else {
                break;
            }
        }
        // In a comment only `crate::` paths count (doc links name items
        // so); in code every path does.
        let in_comment = code_rest.as_bytes()[start] != b[start];
        if segs.len() > 1 && (!in_comment || segs[0] == "crate") {
            raw.push(segs);
        }
        i = j.max(i + 1);
    }
    for segs in raw {
        let mut path = me.to_vec();
        let mut segs = segs.as_slice();
        match segs.first().map(String::as_str) {
            Some("crate") => {
                path.clear();
                segs = &segs[1..];
            }
            Some("super") => {
                while segs.first().map(String::as_str) == Some("super") {
                    path.pop();
                    segs = &segs[1..];
                }
            }
            Some("self") => segs = &segs[1..],
            Some(first) => {
                let mut child = me.to_vec();
                child.push(first.to_string());
                if !is_module(&child) {
                    continue;
                }
            }
            None => continue,
        }
        path.extend(segs.iter().cloned());
        out.push(path);
    }
    out
}

/// The file-level import graph of `src`: file → files it imports.
fn graph(files: &[(String, String)]) -> BTreeMap<String, BTreeSet<String>> {
    let product: Vec<&(String, String)> = files.iter().filter(|(p, _)| !is_test_file(p)).collect();
    let modules: BTreeMap<Vec<String>, String> = product
        .iter()
        .map(|(p, _)| (module_of(p), p.clone()))
        .collect();
    let is_module = |m: &[String]| modules.contains_key(m);
    let resolve = |path: &[String]| {
        (1..=path.len())
            .rev()
            .find_map(|n| modules.get(&path[..n]).cloned())
    };
    let mut g = BTreeMap::new();
    for (rel, text) in product {
        let me = module_of(rel);
        let full = blank_visibility(&blank_literals(text, true));
        let code = blank_visibility(&blank_literals(text, false));
        let mut deps = BTreeSet::new();
        for path in named_paths(&code, &full, &me, &is_module) {
            if let Some(target) = resolve(&path)
                && &target != rel
            {
                deps.insert(target);
            }
        }
        g.insert(rel.clone(), deps);
    }
    g
}

/// The strongly connected components of the graph (Tarjan).
fn components(g: &BTreeMap<String, BTreeSet<String>>) -> Vec<Vec<String>> {
    struct State<'a> {
        g: &'a BTreeMap<String, BTreeSet<String>>,
        index: BTreeMap<&'a str, usize>,
        low: BTreeMap<&'a str, usize>,
        stack: Vec<&'a str>,
        on: BTreeSet<&'a str>,
        out: Vec<Vec<String>>,
    }
    fn visit<'a>(s: &mut State<'a>, v: &'a str) {
        let n = s.index.len();
        s.index.insert(v, n);
        s.low.insert(v, n);
        s.stack.push(v);
        s.on.insert(v);
        for w in &s.g[v] {
            let w = w.as_str();
            if !s.index.contains_key(w) {
                visit(s, w);
                let lw = s.low[w];
                let lv = s.low.get_mut(v).expect("visited");
                *lv = (*lv).min(lw);
            } else if s.on.contains(w) {
                let iw = s.index[w];
                let lv = s.low.get_mut(v).expect("visited");
                *lv = (*lv).min(iw);
            }
        }
        if s.low[v] == s.index[v] {
            let mut comp = Vec::new();
            loop {
                let w = s.stack.pop().expect("on the stack");
                s.on.remove(w);
                comp.push(w.to_string());
                if w == v {
                    break;
                }
            }
            comp.sort();
            s.out.push(comp);
        }
    }
    let mut s = State {
        g,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on: BTreeSet::new(),
        out: Vec::new(),
    };
    for v in g.keys() {
        if !s.index.contains_key(v.as_str()) {
            visit(&mut s, v);
        }
    }
    s.out
}

/// The graph of the core's `src` (or of the folder in `STRUCTURE_SRC`, to
/// check another tree); `STRUCTURE_DUMP=prefix` prints the edges of the
/// files under `prefix`.
fn core_graph() -> BTreeMap<String, BTreeSet<String>> {
    let root = match std::env::var("STRUCTURE_SRC") {
        Ok(dir) => Path::new(&dir).to_path_buf(),
        Err(_) => Path::new(env!("CARGO_MANIFEST_DIR")).join("src"),
    };
    let mut files = Vec::new();
    sources(&root, &root, &mut files);
    let g = graph(&files);
    if let Ok(prefix) = std::env::var("STRUCTURE_DUMP") {
        for (a, deps) in g.iter().filter(|(a, _)| a.starts_with(&prefix)) {
            eprintln!("{a} -> {deps:?}");
        }
    }
    g
}

#[test]
fn no_import_circle_of_more_than_two_files() {
    let g = core_graph();
    // The parser sees the imports it must: a broken one would find none.
    if std::env::var("STRUCTURE_SRC").is_err() {
        assert!(g["world/mod.rs"].contains("world/state.rs"));
        assert!(g["world/state.rs"].contains("world/poses.rs"));
        assert!(g["collider/mod.rs"].contains("handles.rs"));
        // A child module named inline, and an inline `super::` path.
        assert!(g["solver/contact_solver.rs"].contains("solver/contact_solver/wide.rs"));
        assert!(g["world/ccd.rs"].contains("world/collide.rs"));
    }
    assert!(g.values().map(BTreeSet::len).sum::<usize>() > 300);
    let circles: Vec<String> = components(&g)
        .into_iter()
        .filter(|c| c.len() > 2)
        .map(|c| {
            let edges: Vec<String> = c
                .iter()
                .map(|a| {
                    let to: Vec<&str> = g[a]
                        .iter()
                        .filter(|b| c.contains(b))
                        .map(String::as_str)
                        .collect();
                    format!("  {a} -> {}", to.join(", "))
                })
                .collect();
            format!("{} files:\n{}", c.len(), edges.join("\n"))
        })
        .collect();
    assert!(
        circles.is_empty(),
        "import circles of more than two files:\n{}",
        circles.join("\n")
    );
}

#[test]
fn collision_imports_nothing_from_world_or_solver() {
    let g = core_graph();
    let upward: Vec<String> = g
        .iter()
        .filter(|(a, _)| a.starts_with("collision/"))
        .flat_map(|(a, deps)| {
            deps.iter()
                .filter(|b| b.starts_with("world/") || b.starts_with("solver/"))
                .map(move |b| format!("{a} -> {b}"))
        })
        .collect();
    assert!(
        upward.is_empty(),
        "collision imports from world or solver:\n{}",
        upward.join("\n")
    );
}

/// The parser on a made-up tree: nested groups, `self`, renames, globs,
/// inline paths in code and doc links, an inline module, literals with
/// braces, and a test module left out.
#[test]
fn the_parser_reads_every_kind_of_path() {
    let files = vec![
        ("lib.rs".to_string(), String::new()),
        ("a/mod.rs".to_string(), String::new()),
        ("a/b.rs".to_string(), String::new()),
        ("a/c.rs".to_string(), String::new()),
        ("d.rs".to_string(), String::new()),
        ("e.rs".to_string(), String::new()),
        ("f/mod.rs".to_string(), String::new()),
        ("f/g.rs".to_string(), String::new()),
        ("h.rs".to_string(), String::new()),
        ("i.rs".to_string(), String::new()),
        ("j.rs".to_string(), String::new()),
        ("k.rs".to_string(), String::new()),
        ("a/tests.rs".to_string(), "use crate::k::X;".to_string()),
    ];
    let mut files = files;
    files[1].1 = r##"
        mod b;
        pub use self::{b::{self, X as Y}, c::*};
        /// See [`D`](crate::d::D).
        fn f() -> u32 { let s = "{ crate::h::H }"; let c = '{'; crate::e::E::new() }
        #[cfg(test)]
        mod tests { use crate::j::J; }
        mod inner { use super::super::f::g::G; pub(crate) fn z() { i::I; } }
        const R: &str = r#"crate::k::K"#;
    "##
    .to_string();
    let g = graph(&files);
    let deps: Vec<&str> = g["a/mod.rs"].iter().map(String::as_str).collect();
    assert_eq!(deps, ["a/b.rs", "a/c.rs", "d.rs", "e.rs", "f/g.rs"]);
    assert!(!g.contains_key("a/tests.rs"));
}
