//! The module layering ARCHITECTURE.md promises, checked against the code: every module of
//! `src/` may use (`crate::…`) only the modules its row of the dependency table allows, so
//! data flows one way and `model` stays a leaf. A new dependency needs a new table entry (and
//! a reason) — or a better place for the code.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

/// module → modules it may use, from the table between `<!-- deps -->` and `<!-- /deps -->`.
fn allowed() -> BTreeMap<String, BTreeSet<String>> {
    let text = std::fs::read_to_string(Path::new(ROOT).join("ARCHITECTURE.md")).unwrap();
    let a = text
        .find("<!-- deps -->")
        .expect("ARCHITECTURE.md has a <!-- deps --> table");
    let b = text.find("<!-- /deps -->").expect("… and its end marker");
    let mut table = BTreeMap::new();
    for line in text[a..b].lines().filter(|l| l.starts_with("| `")) {
        let cells: Vec<&str> = line.split('|').map(str::trim).collect();
        let names = |cell: &str| -> BTreeSet<String> {
            cell.split(',')
                .map(|s| s.trim().trim_matches('`').to_string())
                .filter(|s| !s.is_empty() && s != "–")
                .collect()
        };
        for m in names(cells[1]) {
            table.insert(m, names(cells[2]));
        }
    }
    table
}

/// The crate modules a source file names as `crate::x` outside comments and its unit-test
/// module (`#[cfg(test)] mod tests`, at the end of a file by convention).
fn used(text: &str) -> BTreeSet<String> {
    let text = match text.find("#[cfg(test)]\nmod tests") {
        Some(i) => &text[..i],
        None => text,
    };
    let mut out = BTreeSet::new();
    for line in text.lines() {
        let code = line.trim_start();
        if code.starts_with("//") {
            continue;
        }
        let mut rest = code;
        while let Some(i) = rest.find("crate::") {
            rest = &rest[i + "crate::".len()..];
            if let Some(group) = rest.strip_prefix('{') {
                let end = group.find('}').unwrap_or(group.len());
                for part in group[..end].split(',') {
                    let m = part.trim().split("::").next().unwrap_or("");
                    if !m.is_empty() {
                        out.insert(m.to_string());
                    }
                }
            } else {
                let m: String = rest
                    .chars()
                    .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                    .collect();
                out.insert(m);
            }
        }
    }
    // The crate root re-exports config's Pipeline.
    if out.remove("Pipeline") {
        out.insert("config".into());
    }
    out
}

fn sources(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            sources(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

#[test]
fn every_module_uses_only_what_the_dependency_table_allows() {
    let table = allowed();
    let src = Path::new(ROOT).join("src");
    let mut files = Vec::new();
    sources(&src, &mut files);
    let mut broken = Vec::new();
    let mut seen = BTreeSet::new();
    for f in files {
        let rel = f.strip_prefix(&src).unwrap();
        let first = rel
            .components()
            .next()
            .unwrap()
            .as_os_str()
            .to_string_lossy();
        let module = first.trim_end_matches(".rs").to_string();
        if module == "lib" || module == "main" || module == "cli" {
            continue; // the crate root and the binary may use everything
        }
        seen.insert(module.clone());
        let Some(ok) = table.get(&module) else {
            broken.push(format!(
                "{}: module {module} has no row in ARCHITECTURE.md's dependency table",
                rel.display()
            ));
            continue;
        };
        for m in used(&std::fs::read_to_string(&f).unwrap()) {
            if m != module && !ok.contains(&m) {
                broken.push(format!(
                    "{}: {module} uses {m}, which its row does not allow",
                    rel.display()
                ));
            }
        }
    }
    for m in table.keys() {
        if !seen.contains(m) {
            broken.push(format!(
                "ARCHITECTURE.md lists {m}, which src/ does not have"
            ));
        }
    }
    assert!(broken.is_empty(), "{}", broken.join("\n"));
}

#[test]
fn the_parser_sees_grouped_and_plain_paths_and_skips_comments() {
    let u = used("use crate::{model::Model, simd};\n// crate::report\nlet x = crate::table::frame;\n#[cfg(test)]\nmod tests {\n    use crate::rng;\n}\n");
    let want: BTreeSet<String> = ["model", "simd", "table"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    assert_eq!(u, want);
}
