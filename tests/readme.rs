//! The option tables in docs/ are the key tables that drive the pipeline and scene checks: a key
//! added, removed or changed in code without its page (or the other way round) fails here. The
//! pipeline file's table lives in docs/pipeline.md, the scene file's in docs/simulator.md.
//! `UPDATE_README=1 cargo test --test readme` rewrites both tables from the code, each in its
//! own page (the variable keeps its old name).

use railgrip::config::rule::{markdown_rows, Key};

fn table(sections: &[(&str, &[&Key])]) -> String {
    let mut t = String::from("| key | default | unit | range | meaning |\n|---|---|---|---|---|\n");
    for (_, keys) in sections {
        t.push_str(&markdown_rows(keys));
    }
    t
}

/// The text between `<!-- keys:NAME ... -->\n` and `<!-- /keys:NAME -->` of `page`.
fn region(text: &str, name: &str, page: &str) -> (usize, usize) {
    let open = format!("<!-- keys:{name} ");
    let close = format!("<!-- /keys:{name} -->");
    let a = text
        .find(&open)
        .unwrap_or_else(|| panic!("{page} has no {open}… marker"));
    let a = a + text[a..].find('\n').expect("marker line ends") + 1;
    let b = text[a..]
        .find(&close)
        .unwrap_or_else(|| panic!("{page} has no {close} marker"))
        + a;
    (a, b)
}

#[test]
fn docs_option_tables_are_the_key_tables() {
    let update = std::env::var("UPDATE_README").as_deref() == Ok("1");
    // (region name, page below the repository root, the key tables it shows)
    for (name, page, sections) in [
        ("pipeline", "docs/pipeline.md", railgrip::config::SECTIONS),
        ("scene", "docs/simulator.md", railgrip::sim::scene::SECTIONS),
    ] {
        let path = format!("{}/{page}", env!("CARGO_MANIFEST_DIR"));
        let mut text =
            std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("cannot read {page}: {e}"));
        let want = table(sections);
        let (a, b) = region(&text, name, page);
        if update {
            text.replace_range(a..b, &want);
            std::fs::write(&path, text).unwrap_or_else(|e| panic!("cannot write {page}: {e}"));
            continue;
        }
        let got = &text[a..b];
        if got != want {
            let line = got
                .lines()
                .zip(want.lines())
                .position(|(g, w)| g != w)
                .unwrap_or(got.lines().count().min(want.lines().count()));
            panic!(
                "{page}'s {name} table differs from the key tables at row {line}:\n {page}: {:?}\n   code: {:?}\n(UPDATE_README=1 cargo test --test readme rewrites {page} from the code)",
                got.lines().nth(line),
                want.lines().nth(line)
            );
        }
    }
}

#[test]
fn every_key_has_a_meaning_and_a_unique_name() {
    let mut seen = std::collections::HashSet::new();
    for (_, keys) in railgrip::config::SECTIONS
        .iter()
        .chain(railgrip::sim::scene::SECTIONS)
    {
        for k in *keys {
            assert!(!k.meaning.is_empty(), "{} has no meaning", k.name);
            // `[contact]` is shared by both files.
            if !k.name.starts_with("contact.") {
                assert!(seen.insert(k.name), "{} listed twice", k.name);
            }
        }
    }
}
