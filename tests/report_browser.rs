//! The HTML report in a real browser: headless Chromium opens it from disk, must log no console
//! message (the report has no scripts, so any message is a fault: a malformed SVG, a blocked
//! resource) and must paint a non-blank page. Skips, saying so, where Chromium is absent; CI
//! installs it (`.ci/run`).

mod common;

use std::path::Path;
use std::process::Command;

fn chromium() -> Option<String> {
    for c in ["chromium", "chromium-browser", "google-chrome"] {
        if Command::new(c)
            .arg("--version")
            .output()
            .is_ok_and(|o| o.status.success())
        {
            return Some(c.to_string());
        }
    }
    None
}

/// The browser, or None where it is absent (a failure under CI=true, which installs it).
fn browser_or_skip() -> Option<String> {
    let b = chromium();
    if b.is_none() {
        // CI installs Chromium (.ci/run): there a missing browser is a failure, not a skip.
        assert!(
            std::env::var("CI").as_deref() != Ok("true"),
            "CI=true but no Chromium: .ci/run should have installed it"
        );
        eprintln!("SKIPPED: no Chromium found (apt-get install chromium); the report was not opened in a browser");
    }
    b
}

/// Opens `html` in headless `browser`: no console message, a non-blank screenshot.
fn assert_renders(browser: &str, html: &Path, dir: &Path) {
    let shot = dir.join("shot.png");
    let profile = dir.join("profile");
    let o = Command::new(browser)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--hide-scrollbars",
            "--enable-logging=stderr",
            "--v=0",
            "--window-size=1300,2000",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .arg(format!("--screenshot={}", shot.display()))
        .arg(format!("file://{}", html.display()))
        .output()
        .unwrap();
    let log = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{browser} failed: {log}");
    let console: Vec<&str> = log.lines().filter(|l| l.contains("CONSOLE")).collect();
    assert!(console.is_empty(), "console messages: {console:#?}");
    assert_non_blank(&shot);
}

#[test]
fn report_renders_in_headless_chromium_without_console_errors() {
    let Some(browser) = browser_or_skip() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let camp = dir.path().join("campaign");
    common::two_run_campaign(&camp);
    std::fs::write(camp.join("broken.csv"), "t,v_radar\n0,abc\n").unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_railgrip"))
        .args(["run", "campaign", "--out", "out"])
        .current_dir(dir.path())
        .output()
        .unwrap();
    assert_eq!(
        o.status.code(),
        Some(3),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert_renders(
        &browser,
        &dir.path().join("out/report/index.html"),
        dir.path(),
    );
}

#[test]
fn study_report_renders_in_headless_chromium_without_console_errors() {
    let Some(browser) = browser_or_skip() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    common::two_run_campaign(&dir.path().join("campaign"));
    std::fs::write(
        dir.path().join("plan.toml"),
        "[[grid]]\nlabel = \"Polach\"\ntrain.model = \"polach_pooled\"\n[[grid]]\nlabel = \"LM\"\ntrain.layers = [[3], [6]]\n",
    )
    .unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_railgrip"))
        .args(["study", "campaign", "--plan", "plan.toml", "--out", "st"])
        .current_dir(dir.path())
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let html = dir.path().join("st/study.html");
    let page = std::fs::read_to_string(&html).unwrap();
    for want in ["Recommendation", "Pareto fronts", "<svg", "All cells", "★"] {
        assert!(page.contains(want), "{want} missing");
    }
    assert_renders(&browser, &html, dir.path());
}

/// The screenshot has ink: many pixels differ from the background, in several colours.
fn assert_non_blank(path: &Path) {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).unwrap();
    let bytes = &buf[..info.buffer_size()];
    let ch = info.color_type.samples();
    let px: Vec<&[u8]> = bytes.chunks_exact(ch).collect();
    let bg = px[0];
    let ink = px.iter().filter(|p| p[..3] != bg[..3]).count();
    let mut colours: Vec<[u8; 3]> = px.iter().map(|p| [p[0], p[1], p[2]]).collect();
    colours.sort_unstable();
    colours.dedup();
    eprintln!(
        "screenshot {}×{}: {:.1} % ink, {} colours",
        info.width,
        info.height,
        100.0 * ink as f64 / px.len() as f64,
        colours.len()
    );
    assert!(
        ink as f64 > 0.05 * px.len() as f64,
        "screenshot is (nearly) blank"
    );
    assert!(
        colours.len() > 50,
        "screenshot has {} colours",
        colours.len()
    );
}
