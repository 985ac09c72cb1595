//! The report's campaign-model section: which candidate `train.model` chose and why, every
//! candidate's held-out scores, and the chosen model replayed on the runs' own estimates per
//! speed band (bias and RMSE, axle 2) — where a model that cannot follow the level's fall with
//! speed shows itself.

use std::fmt::Write as _;

use super::{esc, opt, Inputs};
use crate::identify::choice::Choice;
use crate::model::Model;

/// The section: the choice, the candidates' table, and the chosen model per speed band.
pub(super) fn campaign_model(h: &mut String, i: &Inputs, choice: &Choice, chosen: Option<&Model>) {
    let file = i.camp.chosen_model.as_deref().unwrap_or("–");
    let _ = writeln!(
        *h,
        "<h2>Campaign model</h2>\n<p>The campaign's model is <b>{}</b> (<code>{}</code>; <code>train.model = \"{}\"</code>): {}. The replay MCAP files and the C header <code>{}</code> are of this model.</p>",
        esc(&choice.chosen),
        esc(file),
        esc(&choice.setting),
        esc(&choice.reason),
        esc(&file.replace(".json", ".h")),
    );
    if !choice.candidates.is_empty() {
        let _ = writeln!(
            *h,
            "<p class=\"note\">Each candidate fitted as the campaign fits it (one start) on all runs but the held-out ones, {} fold(s), and scored on the held-out runs' own estimates (all axles, every <code>train.decimate</code>-th sample, at each run's ambient temperature); the Polach form the campaign chose is refitted per fold, not searched again.</p>\n<table><tr><th class=\"l\">candidate</th><th>model</th><th>parameters</th><th>held-out RMSE μ</th><th>bias μ</th><th>worst run RMSE μ</th><th class=\"l\">note</th></tr>",
            choice.folds
        );
        for c in &choice.candidates {
            let mark = if c.name == choice.chosen { " ✔" } else { "" };
            let _ = writeln!(
                *h,
                "<tr><td class=\"l\">{}{mark}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td class=\"l\">{}</td></tr>",
                esc(&c.name),
                esc(&c.architecture),
                c.parameters,
                opt(c.rmse_mu, 5),
                c.bias_mu.map_or("–".into(), |b| format!("{b:+.5}")),
                opt(c.worst_run_rmse_mu, 5),
                esc(c.error.as_deref().unwrap_or("")),
            );
        }
        h.push_str("</table>\n");
    }
    if chosen.is_some() {
        by_speed_band(h, i);
    }
}

/// The chosen model at every valid axle-2 sample of the training condition's runs (its own
/// Δv, dΔv/dt, v and the run's ambient temperature) against the estimate, per speed band
/// (gathered as the runs were read).
fn by_speed_band(h: &mut String, i: &Inputs) {
    let Some(bands) = &i.across.bands else {
        return;
    };
    h.push_str("<h3>The campaign model per speed band</h3>\n<p class=\"note\">Replayed at every valid sample of axle 2 (its own inputs, the run's ambient temperature) against the estimate; the speed is the vehicle's at the sample. A bias that grows with speed is a level the model does not let fall with speed.</p>\n<table><tr><th class=\"l\">speed band (km/h)</th><th>samples</th><th>bias μ</th><th>RMSE μ</th></tr>\n");
    for b in bands.bands() {
        let _ = writeln!(
            *h,
            "<tr><td class=\"l\">{:.0} – {:.0}</td><td>{}</td><td>{:+.5}</td><td>{:.5}</td></tr>",
            b.lo_kmh, b.hi_kmh, b.stats.n, b.stats.bias, b.stats.rmse
        );
    }
    h.push_str("</table>\n");
}
