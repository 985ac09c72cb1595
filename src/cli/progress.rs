//! Progress on stderr: bars on a terminal, plain lines otherwise — for a campaign (`run`) and a
//! study (`study`). The library reports events through its `Progress` trait; this is the one
//! place that draws them.

use std::io::IsTerminal as _;
use std::sync::Mutex;

use indicatif::{ProgressBar, ProgressStyle};
use railgrip::campaign::{self, RunRecord};
use railgrip::study::{self, CellResult};

/// Progress on stderr: a bar per stage on a terminal, plain lines otherwise.
pub(super) struct Bars {
    terminal: bool,
    estimate: Mutex<Option<ProgressBar>>,
    train: Mutex<Option<ProgressBar>>,
}

impl Bars {
    pub(super) fn new() -> Bars {
        Bars {
            terminal: std::io::stderr().is_terminal(),
            estimate: Mutex::new(None),
            train: Mutex::new(None),
        }
    }
}

fn run_line(r: &RunRecord) -> String {
    match (r.ok(), r.reused) {
        (true, true) => format!("run        {}: unchanged, reused", r.run),
        (true, false) => format!("run        {}: ok ({:.2} s)", r.run, r.duration_s),
        _ => format!(
            "run        {}: FAILED: {}",
            r.run,
            r.error.as_deref().unwrap_or("")
        ),
    }
}

impl<'a> campaign::Progress<campaign::Event<'a>> for Bars {
    fn event(&self, e: campaign::Event<'a>) {
        match e {
            campaign::Event::EstimateStarts {
                runs,
                source,
                threads,
            } => {
                if self.terminal {
                    let bar = ProgressBar::new(runs as u64);
                    bar.set_style(
                        ProgressStyle::with_template(
                            "{prefix:>10} [{bar:30}] {pos}/{len} {elapsed_precise} {wide_msg}",
                        )
                        .expect("valid template")
                        .progress_chars("=> "),
                    );
                    bar.set_prefix("estimate");
                    *self.estimate.lock().expect("not poisoned") = Some(bar);
                } else {
                    eprintln!(
                        "estimate   {runs} run(s) from {} on {threads} thread(s)",
                        source.display()
                    );
                }
            }
            campaign::Event::RunDone(r) => {
                let line = run_line(r);
                match &*self.estimate.lock().expect("not poisoned") {
                    Some(b) => {
                        if !r.ok() {
                            b.println(line.clone());
                        }
                        b.set_message(line);
                        b.inc(1);
                    }
                    None => eprintln!("{line}"),
                }
            }
            campaign::Event::TrainStarts => {
                if self.terminal {
                    let b = ProgressBar::new_spinner();
                    b.set_style(
                        ProgressStyle::with_template(
                            "{prefix:>10} {spinner} {elapsed_precise} {wide_msg}",
                        )
                        .expect("valid template"),
                    );
                    b.set_prefix("train");
                    b.enable_steady_tick(std::time::Duration::from_millis(120));
                    *self.train.lock().expect("not poisoned") = Some(b);
                } else {
                    eprintln!("train      network and Polach fits on the pooled estimates");
                }
            }
            campaign::Event::Epoch(e) => {
                if let Some(b) = &*self.train.lock().expect("not poisoned") {
                    b.set_message(format!(
                        "epoch {}  train MSE {:.3e}  val MSE {:.3e}",
                        e.epoch, e.train_mse, e.val_mse
                    ));
                }
            }
            campaign::Event::StageDone(stage) => {
                let slot = match stage {
                    campaign::Stage::Estimate => &self.estimate,
                    campaign::Stage::Train => &self.train,
                    campaign::Stage::Report => return,
                };
                if let Some(b) = slot.lock().expect("not poisoned").take() {
                    b.finish_and_clear();
                }
            }
        }
    }
}

/// Progress on stderr: a bar over the cells on a terminal, plain lines otherwise.
pub(super) struct CellBar {
    terminal: bool,
    bar: Mutex<Option<ProgressBar>>,
}

fn cell_line(r: &CellResult, what: &str) -> String {
    match &r.error {
        Some(e) => format!("cell       {}: FAILED: {e}", r.name),
        None => format!(
            "cell       {}: {what} {}",
            r.name,
            match (what, &r.eval) {
                ("timed", Some(e)) => format!("{:.1} ns per μ", e.single_ns),
                _ => format!(
                    "{:.2} s, held-out RMSE {:.5}",
                    r.train_s.unwrap_or(f64::NAN),
                    r.held_out_rmse.unwrap_or(f64::NAN)
                ),
            }
        ),
    }
}

impl CellBar {
    pub(super) fn new() -> CellBar {
        CellBar {
            terminal: std::io::stderr().is_terminal(),
            bar: Mutex::new(None),
        }
    }

    /// Clears the bar (the study is over).
    pub(super) fn finish(&self) {
        if let Some(b) = self.bar.lock().expect("not poisoned").take() {
            b.finish_and_clear();
        }
    }
}

impl<'a> study::Progress<study::Event<'a>> for CellBar {
    fn event(&self, e: study::Event<'a>) {
        match e {
            study::Event::Estimating {
                conditionings,
                runs,
            } => eprintln!("estimate   {runs} run(s) × {conditionings} conditioning setting(s) (reused when unchanged)"),
            study::Event::Planned {
                cells,
                reused,
                estimated_s,
            } => {
                eprintln!(
                    "study      {cells} cell(s), {reused} reused; training estimated at {:.1} min",
                    estimated_s / 60.0
                );
                if self.terminal {
                    // Each cell is trained, then timed: two steps per new cell.
                    let b = ProgressBar::new(2 * (cells - reused) as u64);
                    b.set_style(
                        ProgressStyle::with_template(
                            "{prefix:>10} [{bar:30}] {pos}/{len} {elapsed_precise} (eta {eta}) {wide_msg}",
                        )
                        .expect("valid template")
                        .progress_chars("=> "),
                    );
                    b.set_prefix("cells");
                    *self.bar.lock().expect("not poisoned") = Some(b);
                }
            }
            study::Event::Trained(r) | study::Event::Timed(r) => {
                let what = if matches!(e, study::Event::Timed(_)) { "timed" } else { "trained" };
                let line = cell_line(r, what);
                match &*self.bar.lock().expect("not poisoned") {
                    Some(b) => {
                        if r.error.is_some() {
                            b.println(line.clone());
                        }
                        b.set_message(line);
                        b.inc(if r.error.is_some() { 2 } else { 1 });
                    }
                    None => eprintln!("{line}"),
                }
            }
        }
    }
}
