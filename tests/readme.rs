//! README's option tables are the key tables that drive the pipeline and scene checks: a key
//! added, removed or changed in code without README (or the other way round) fails here.
//! `UPDATE_README=1 cargo test --test readme` rewrites the tables from the code.

use railgrip::config::rule::{markdown_rows, Key};

const README: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/README.md");

fn table(sections: &[(&str, &[&Key])]) -> String {
    let mut t = String::from("| key | default | unit | range | meaning |\n|---|---|---|---|---|\n");
    for (_, keys) in sections {
        t.push_str(&markdown_rows(keys));
    }
    t
}

/// The text between `<!-- keys:NAME ... -->\n` and `<!-- /keys:NAME -->`.
fn region(text: &str, name: &str) -> (usize, usize) {
    let open = format!("<!-- keys:{name} ");
    let close = format!("<!-- /keys:{name} -->");
    let a = text
        .find(&open)
        .unwrap_or_else(|| panic!("README has no {open}… marker"));
    let a = a + text[a..].find('\n').expect("marker line ends") + 1;
    let b = text[a..]
        .find(&close)
        .unwrap_or_else(|| panic!("README has no {close} marker"))
        + a;
    (a, b)
}

#[test]
fn readme_option_tables_are_the_key_tables() {
    let mut text = std::fs::read_to_string(README).unwrap();
    let update = std::env::var("UPDATE_README").as_deref() == Ok("1");
    for (name, sections) in [
        ("pipeline", railgrip::config::SECTIONS),
        ("scene", railgrip::sim::scene::SECTIONS),
    ] {
        let want = table(sections);
        let (a, b) = region(&text, name);
        if update {
            text.replace_range(a..b, &want);
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
                "README's {name} table differs from the key tables at row {line}:\n README: {:?}\n   code: {:?}\n(UPDATE_README=1 cargo test --test readme rewrites README from the code)",
                got.lines().nth(line),
                want.lines().nth(line)
            );
        }
    }
    if update {
        std::fs::write(README, text).unwrap();
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
