//! The study report (`study.html`): self-contained HTML like the validation report — no
//! scripts, plots as inline SVG. The recommendation for the stated budgets, the two Pareto
//! fronts (accuracy vs training time, accuracy vs evaluation ns per μ), and every cell.

use std::fmt::Write as _;

use plotters::style::RGBColor;

use super::{CellResult, Outcome};
use crate::report::plot::{chart_axes, Series, PALETTE};
use crate::report::{esc, page_head};

fn num(v: Option<f64>, d: usize) -> String {
    v.filter(|x| x.is_finite())
        .map_or("–".into(), |x| format!("{x:.d$}"))
}

/// The whole page.
pub fn render(o: &Outcome) -> String {
    let mut h = String::new();
    let measure = if o.by_truth {
        "supported-cell RMSE against the true law (held-out runs' truth)"
    } else {
        "RMSE against the held-out runs' estimates"
    };
    let _ = write!(
        h,
        r#"{head}<h1>railgrip study</h1>
<p>Campaign <code>{archive}</code>, plan <code>{plan}</code>, base pipeline <code>{pipe}</code>.
Trained on {nt} run(s) of <b>{cond}</b> rail ({train}); held out: {held}. Accuracy: {measure}, μ.
{n} cells, {jobs} thread(s), {wall:.1} s. railgrip {ver}.</p>
"#,
        head = page_head(&format!("railgrip study — {}", o.archive)),
        archive = esc(&o.archive),
        plan = esc(&o.plan),
        pipe = esc(&o.pipeline),
        nt = o.train_runs.len(),
        cond = esc(&o.condition),
        train = esc(&o.train_runs.join(", ")),
        held = esc(&o.held_out.join(", ")),
        n = o.cells.len(),
        jobs = o.jobs,
        wall = o.wall_s,
        ver = env!("CARGO_PKG_VERSION"),
    );
    recommendation(&mut h, o);
    fronts(&mut h, o);
    table(&mut h, o);
    ladder(&mut h, o);
    if !o.notes.is_empty() {
        h.push_str("<h2>Notes</h2>\n<ul>\n");
        for n in &o.notes {
            let _ = writeln!(h, "<li>{}</li>", esc(n));
        }
        h.push_str("</ul>\n");
    }
    h.push_str("<p class=\"note\">Training times are wall times with the cells side by side on the threads above; evaluation times were measured afterwards, one cell at a time (best of 5 repetitions of ≥ 20 ms over the held-out inputs). Every other figure is the same for the same inputs and plan.</p>\n</body></html>\n");
    h
}

fn recommendation(h: &mut String, o: &Outcome) {
    let budgets = match (o.budget_ns, o.budget_train_s) {
        (None, None) => "no budget given".to_string(),
        (a, b) => {
            let mut v = vec![];
            if let Some(ns) = a {
                v.push(format!("≤ {ns} ns per μ (single call)"));
            }
            if let Some(s) = b {
                v.push(format!("≤ {s} s of training"));
            }
            v.join(", ")
        }
    };
    h.push_str("<h2>Recommendation</h2>\n");
    match o
        .recommended
        .as_ref()
        .and_then(|k| o.cells.iter().find(|c| &c.key == k))
    {
        Some(c) => {
            let _ = writeln!(
                h,
                "<p>For {budgets}: <b>{}</b> ({}) — accuracy {} μ, training {} s, {} ns per μ, file {} bytes (<code>cells/{}.model.json</code>).</p>",
                esc(&c.name),
                esc(&c.architecture),
                num(Some(c.accuracy(o.by_truth)), 5),
                num(c.train_s, 2),
                num(c.eval.as_ref().map(|e| e.single_ns), 1),
                c.file_bytes,
                c.key
            );
        }
        None => {
            let _ = writeln!(
                h,
                "<p class=\"failed\">For {budgets}: no cell meets the budgets.</p>"
            );
        }
    }
}

fn fronts(h: &mut String, o: &Outcome) {
    h.push_str("<h2>Pareto fronts</h2>\n<div class=\"figs\">\n");
    let groups: Vec<&str> = {
        let mut g: Vec<&str> = o.cells.iter().map(|c| c.group.as_str()).collect();
        g.dedup();
        let mut seen = Vec::new();
        for x in g {
            if !seen.contains(&x) {
                seen.push(x);
            }
        }
        seen
    };
    let plot =
        |title: &str, x_desc: &str, cost: &dyn Fn(&CellResult) -> Option<f64>, front: &[String]| {
            let mut series: Vec<Series> = groups
                .iter()
                .enumerate()
                .map(|(k, g)| Series {
                    name: (*g).to_string(),
                    color: PALETTE[k % PALETTE.len()],
                    pts: o
                        .cells
                        .iter()
                        .filter(|c| c.ok() && c.group == *g)
                        .filter_map(|c| Some((cost(c)?, c.accuracy(o.by_truth))))
                        .filter(|(x, y)| *x > 0.0 && x.is_finite() && y.is_finite())
                        .collect(),
                    dots: true,
                })
                .collect();
            series.push(Series {
                name: "front".into(),
                color: RGBColor(0, 0, 0),
                pts: front
                    .iter()
                    .filter_map(|k| o.cells.iter().find(|c| &c.key == k))
                    .filter_map(|c| Some((cost(c)?, c.accuracy(o.by_truth))))
                    .collect(),
                dots: false,
            });
            chart_axes(title, x_desc, "error (μ)", &series, true, true, &[])
        };
    for fig in [
        plot(
            "Accuracy vs training time",
            "training time (s)",
            &|c| c.train_s,
            &o.pareto_train,
        ),
        plot(
            "Accuracy vs evaluation time",
            "ns per μ (Rust single call)",
            &|c| c.eval.as_ref().map(|e| e.single_ns),
            &o.pareto_eval,
        ),
    ] {
        match fig {
            Ok(svg) => h.push_str(&svg),
            Err(e) => {
                let _ = writeln!(h, "<p class=\"failed\">{}</p>", esc(&e.to_string()));
            }
        }
    }
    h.push_str("</div>\n");
}

fn table(h: &mut String, o: &Outcome) {
    let _ = writeln!(
        h,
        "<h2>All cells</h2>\n<p class=\"note\">Sorted by accuracy. ★ recommended; T on the training-time front, E on the evaluation-time front. ns: the Rust evaluator (single call, batch: fast tanh, SIMD, creep region and support blend included), and the network alone in a plain scalar loop over the file's layers with the C library's tanh; |Δμ| libm: the largest difference in μ that loop makes between the C library's tanh and the evaluators' fast one.</p>\n<table>\n<tr><th></th><th class=\"l\">cell</th><th>net</th><th>params</th><th>samples</th><th>epochs</th><th>train s</th><th>est. s</th><th>ns single</th><th>ns batch</th><th>ns plain libm loop</th><th>|Δμ| libm</th><th>bytes</th><th>held-out RMSE</th><th>truth RMSE</th><th>truth cells</th><th>μ̂&lt;0</th></tr>"
    );
    let mut order: Vec<&CellResult> = o.cells.iter().collect();
    order.sort_by(|a, b| {
        a.accuracy(o.by_truth)
            .total_cmp(&b.accuracy(o.by_truth))
            .then(a.name.cmp(&b.name))
    });
    for c in order {
        let e = c.eval.as_ref();
        let mut mark = String::new();
        if o.recommended.as_deref() == Some(c.key.as_str()) {
            mark.push('★');
        }
        if o.pareto_train.contains(&c.key) {
            mark.push('T');
        }
        if o.pareto_eval.contains(&c.key) {
            mark.push('E');
        }
        if let Some(err) = &c.error {
            let _ = writeln!(
                h,
                "<tr class=\"failed\"><td></td><td class=\"l\">{}</td><td class=\"l\" colspan=\"15\">failed: {}</td></tr>",
                esc(&c.name),
                esc(err)
            );
            continue;
        }
        let _ = writeln!(
            h,
            "<tr><td>{mark}</td><td class=\"l\">{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            esc(&c.name),
            esc(&c.architecture),
            c.parameters,
            c.train_samples,
            c.epochs,
            num(c.train_s, 2),
            num(Some(c.estimated_train_s), 1),
            num(e.map(|e| e.single_ns), 1),
            num(e.map(|e| e.batch_ns), 1),
            num(e.and_then(|e| e.plain_libm_ns), 1),
            e.and_then(|e| e.libm_max_diff)
                .map_or("–".into(), |d| format!("{d:.1e}")),
            c.file_bytes,
            num(c.held_out_rmse, 5),
            num(c.truth_rmse, 5),
            c.truth_cells.map_or("–".into(), |n| n.to_string()),
            c.truth_negative_cells.map_or("–".into(), |n| n.to_string()),
        );
    }
    h.push_str("</table>\n");
}

fn ladder(h: &mut String, o: &Outcome) {
    if !o.simulator.is_empty() {
        h.push_str("<h2>Simulator step</h2>\n<p class=\"note\">Each scene at each step against the same scene at the reference step: wall time best of 3, real-time factor, RMS of μ over every axle and output sample, largest |v − v_ref|.</p>\n<table>\n<tr><th class=\"l\">scene</th><th>step ms</th><th>reference ms</th><th>wall s</th><th>× real time</th><th>RMS μ error</th><th>max |v − v_ref| m/s</th></tr>\n");
        for r in &o.simulator {
            let _ = writeln!(
                h,
                "<tr><td class=\"l\">{}</td><td>{}</td><td>{}</td><td>{:.4}</td><td>{:.0}</td><td>{:.5}</td><td>{:.4}</td></tr>",
                esc(&r.scene),
                r.step_ms,
                r.reference_step_ms,
                r.wall_s,
                r.real_time_factor,
                r.rms_mu_error,
                r.max_v_error_mps
            );
        }
        h.push_str("</table>\n");
    }
    if !o.contact.is_empty() {
        h.push_str("<h2>Contact law</h2>\n<p class=\"note\">F_x over 32 longitudinal creepages on the base pipeline's wheel patch against FASTSIM on the reference grid, as a fraction of μN; time per call.</p>\n<table>\n<tr><th class=\"l\">law</th><th>ns per call</th><th>RMS error</th><th>max error</th><th class=\"l\">reference</th></tr>\n");
        for r in &o.contact {
            let _ = writeln!(
                h,
                "<tr><td class=\"l\">{}</td><td>{:.1}</td><td>{:.2e}</td><td>{:.2e}</td><td class=\"l\">{}</td></tr>",
                esc(&r.law),
                r.ns_per_call,
                r.rms_error,
                r.max_error,
                esc(&r.reference)
            );
        }
        h.push_str("</table>\n");
    }
}
