//! `railgrip ingest`: read one log, print its summary, optionally write the resampled table.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::Context;
use railgrip::ingest::{write_runlog_parquet, RunLog};

use super::{PipelineArg, EXIT_LOSSY, EXIT_OK};

#[derive(clap::Args)]
pub struct Args {
    /// The log to read: .csv (with optional <stem>.meta.toml sidecar) or .mcap; a path,
    /// file://PATH or s3://BUCKET/KEY (AWS_* environment variables: docs/cluster.md).
    #[arg(value_name = "FILE")]
    file: String,
    #[command(flatten)]
    pipeline: PipelineArg,
    /// Write the resampled log to <DIR>/<stem>.runlog.parquet (the directory is created): a
    /// path, file://PATH or s3://BUCKET/PREFIX.
    #[arg(long, value_name = "DIR")]
    out: Option<String>,
}

pub fn run(args: Args) -> anyhow::Result<u8> {
    let pipeline = args.pipeline.load()?;
    let folder = args
        .out
        .as_deref()
        .map(railgrip::store::OutFolder::at)
        .transpose()?;
    let log =
        railgrip::ingest::ingest_source(&railgrip::ingest::LogSource::at(&args.file)?, &pipeline)?;
    print!("{}", summary(&log));
    if let Some(folder) = &folder {
        let dir = folder.dir();
        let out = dir.join(format!(
            "{}.runlog.parquet",
            stem(std::path::Path::new(&args.file))
        ));
        // Errors name the output's URI, not a staging folder.
        std::fs::create_dir_all(dir)
            .with_context(|| format!("{}: cannot create the output directory", dir.display()))
            .and_then(|_| write_runlog_parquet(&log, &out).map_err(anyhow::Error::from))
            .map_err(|e| anyhow::anyhow!(folder.explain(&format!("{e:#}"))))?;
        folder.finish(std::slice::from_ref(&out))?;
        let size = std::fs::metadata(&out).map(|m| m.len()).unwrap_or(0);
        println!(
            "wrote      {} ({:.1} MB, {} rows)",
            folder.name_of(&out),
            size as f64 / 1e6,
            log.len()
        );
    }
    Ok(if log.lost_data() { EXIT_LOSSY } else { EXIT_OK })
}

pub fn stem(p: &Path) -> String {
    p.file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "run".into())
}

fn opt<T: std::fmt::Display>(v: &Option<T>, unit: &str) -> String {
    v.as_ref()
        .map(|x| format!("{x}{unit}"))
        .unwrap_or_else(|| "?".into())
}

/// The human summary printed by `railgrip ingest`.
pub fn summary(log: &RunLog) -> String {
    let mut s = String::new();
    let m = &log.metadata;
    let _ = writeln!(s, "file       {} ({})", log.source.display(), log.format);
    let _ = writeln!(
        s,
        "run        vehicle {} · condition {} · ambient {} · initial speed {}",
        opt(&m.vehicle, ""),
        opt(&m.condition, ""),
        opt(&m.ambient_temperature_c, " °C"),
        opt(&m.initial_speed_kmh, " km/h"),
    );
    if !m.other.is_empty() {
        let other: Vec<String> = m.other.iter().map(|(k, v)| format!("{k}={v}")).collect();
        let _ = writeln!(s, "metadata   {}", other.join(" · "));
    }
    let _ = writeln!(
        s,
        "duration   {:.3} s: {} samples at {} Hz from t = {:.3} s to {:.3} s ({} invalid)",
        log.duration_s(),
        log.len(),
        log.sample_rate_hz,
        log.time_s.first().copied().unwrap_or(0.0),
        log.time_s.last().copied().unwrap_or(0.0),
        log.invalid_samples()
    );
    let _ = writeln!(
        s,
        "\n{:<8} {:<6} {:>9} {:>10} {:>10} {:>10} {:>10}  source",
        "signal", "unit", "samples", "rate Hz", "max step", "min", "max"
    );
    for c in &log.channels {
        let unit = c.signal.quantity().canonical().symbol();
        let _ = writeln!(
            s,
            "{:<8} {:<6} {:>9} {:>10.1} {:>8.1}ms {:>10.3} {:>10.3}  {}{}",
            c.signal.key(),
            unit,
            c.samples,
            c.rate_hz,
            c.max_step_s * 1e3,
            c.min,
            c.max,
            c.source,
            if c.dropped > 0 {
                format!(" ({} dropped)", c.dropped)
            } else {
                String::new()
            }
        );
    }
    let _ = writeln!(s);
    if log.gaps.is_empty() {
        let _ = writeln!(s, "gaps       none");
    } else {
        let _ = writeln!(s, "gaps       {} not interpolated:", log.gaps.len());
        for g in log.gaps.iter().take(10) {
            let _ = writeln!(
                s,
                "           {:<8} {:.3} s … {:.3} s ({:.0} ms)",
                g.signal.key(),
                g.from_s,
                g.to_s,
                (g.to_s - g.from_s) * 1e3
            );
        }
        if log.gaps.len() > 10 {
            let _ = writeln!(s, "           … and {} more", log.gaps.len() - 10);
        }
    }
    if log.warnings.is_empty() {
        let _ = writeln!(s, "warnings   none");
    } else {
        let _ = writeln!(s, "warnings   {}:", log.warnings.len());
        for w in &log.warnings {
            let _ = writeln!(s, "           - {}", w.message);
        }
    }
    s
}
