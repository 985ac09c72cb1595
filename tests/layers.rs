//! The layering ARCHITECTURE.md promises, checked against the code, at two levels:
//!
//! - **Crates**: every workspace crate depends only on the workspace crates its row of the crate
//!   table allows, and the lean crates (contact, simd, io, model) on nothing outside their
//!   row's external list — so a simulator, an FMU or a Python evaluator that embeds
//!   `railgrip-model` never builds polars, burn, argmin or plotters.
//! - **Modules** of the pipeline crate (`crates/railgrip/src`): every module may use
//!   (`crate::…`) only the modules its row of the module table allows, so data flows one way.
//!   The lean crates appear there under the names the pipeline re-exports them by (`contact`,
//!   `model`, `simd`, `atomic`, `input`).
//!
//! A new dependency needs a new table entry (and a reason) — or a better place for the code.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

/// Names in a table cell: "`a`, `b`" → {a, b}; "–" → {}.
fn names(cell: &str) -> BTreeSet<String> {
    cell.split(',')
        .map(|s| s.trim().trim_matches('`').to_string())
        .filter(|s| !s.is_empty() && s != "–")
        .collect()
}

/// The rows of the table between `<!-- NAME -->` and `<!-- /NAME -->` in ARCHITECTURE.md:
/// first cell (one or more names) → the other cells' names.
fn table(marker: &str) -> BTreeMap<String, Vec<BTreeSet<String>>> {
    let text = std::fs::read_to_string(Path::new(ROOT).join("ARCHITECTURE.md")).unwrap();
    let open = format!("<!-- {marker} -->");
    let close = format!("<!-- /{marker} -->");
    let a = text
        .find(&open)
        .unwrap_or_else(|| panic!("ARCHITECTURE.md has a {open} table"));
    let b = text.find(&close).expect("… and its end marker");
    let mut rows = BTreeMap::new();
    for line in text[a..b].lines().filter(|l| l.starts_with("| `")) {
        let cells: Vec<&str> = line.split('|').map(str::trim).collect();
        let rest: Vec<BTreeSet<String>> =
            cells[2..cells.len() - 1].iter().map(|c| names(c)).collect();
        for m in names(cells[1]) {
            rows.insert(m, rest.clone());
        }
    }
    rows
}

/// A crate's manifest: its package name and the names in its `[dependencies]` table (not
/// dev-dependencies: tests may use anything).
fn manifest(path: &Path) -> (String, BTreeSet<String>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut name = String::new();
    let mut deps = BTreeSet::new();
    let mut section = String::new();
    for line in text.lines().map(str::trim) {
        if line.starts_with('[') {
            section = line.to_string();
            continue;
        }
        let Some((key, value)) = line.split_once('=') else {
            continue;
        };
        let key = key.trim().trim_end_matches(".workspace").trim();
        match section.as_str() {
            "[package]" if key == "name" => name = value.trim().trim_matches('"').to_string(),
            "[dependencies]" => {
                deps.insert(key.to_string());
            }
            _ => {}
        }
    }
    (name, deps)
}

#[test]
fn every_crate_depends_only_on_what_the_crate_table_allows() {
    let rows = table("crates");
    let mut manifests: Vec<PathBuf> = vec![Path::new(ROOT).join("Cargo.toml")];
    for e in std::fs::read_dir(Path::new(ROOT).join("crates")).unwrap() {
        let p = e.unwrap().path().join("Cargo.toml");
        if p.exists() {
            manifests.push(p);
        }
    }
    let workspace: BTreeSet<String> = manifests.iter().map(|m| manifest(m).0).collect();
    let mut broken = Vec::new();
    let mut seen = BTreeSet::new();
    for m in &manifests {
        let (name, deps) = manifest(m);
        seen.insert(name.clone());
        let Some(row) = rows.get(&name) else {
            broken.push(format!(
                "{}: crate {name} has no row in ARCHITECTURE.md's crate table",
                m.display()
            ));
            continue;
        };
        let (internal, external) = (&row[0], &row[1]);
        for d in &deps {
            let ok = if workspace.contains(d) {
                internal.contains(d)
            } else {
                // "any" in the external column: the pipeline and the binary take what they need.
                external.contains("any") || external.contains(d)
            };
            if !ok {
                broken.push(format!(
                    "{name} depends on {d}, which its row in the crate table does not allow"
                ));
            }
        }
    }
    for c in rows.keys() {
        if !seen.contains(c) {
            broken.push(format!(
                "ARCHITECTURE.md lists crate {c}, which the workspace does not have"
            ));
        }
    }
    assert!(broken.is_empty(), "{}", broken.join("\n"));
}

#[test]
fn the_model_crate_builds_nothing_heavy() {
    // Whatever the table says: the front door for evaluation stays lean.
    let (_, deps) = manifest(&Path::new(ROOT).join("crates/railgrip-model/Cargo.toml"));
    for heavy in [
        "polars", "burn", "argmin", "plotters", "mcap", "faer", "ndarray", "rayon",
    ] {
        assert!(
            !deps.contains(heavy),
            "railgrip-model depends on {heavy}: keep it in the pipeline crate"
        );
    }
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
    // Items the crate root defines or re-exports stand for the module they come from.
    for (item, module) in [("Pipeline", "config")] {
        if out.remove(item) {
            out.insert(module.into());
        }
    }
    out
}

fn sources(dir: &Path, out: &mut Vec<PathBuf>) {
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
    let table: BTreeMap<String, BTreeSet<String>> = table("deps")
        .into_iter()
        .map(|(k, v)| (k, v[0].clone()))
        .collect();
    let src = Path::new(ROOT).join("crates/railgrip/src");
    let mut files = Vec::new();
    sources(&src, &mut files);
    let mut broken = Vec::new();
    let mut seen = BTreeSet::new();
    // The lean crates the pipeline re-exports under module names: rows of the table, no files.
    for reexported in ["contact", "model", "simd", "atomic", "input"] {
        seen.insert(reexported.to_string());
    }
    for f in files {
        let rel = f.strip_prefix(&src).unwrap();
        let first = rel
            .components()
            .next()
            .unwrap()
            .as_os_str()
            .to_string_lossy();
        let module = first.trim_end_matches(".rs").to_string();
        if module == "lib" {
            continue; // the crate root may use everything
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
                "ARCHITECTURE.md lists {m}, which crates/railgrip/src does not have"
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

#[test]
fn the_manifest_reader_sees_dependencies_not_dev_dependencies() {
    let (name, deps) = manifest(&Path::new(ROOT).join("crates/railgrip-model/Cargo.toml"));
    assert_eq!(name, "railgrip-model");
    assert!(deps.contains("railgrip-contact") && deps.contains("serde"));
    assert!(!deps.contains("tempfile"), "tempfile is a dev-dependency");
}
