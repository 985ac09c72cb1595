//! A campaign's Polach fits: pooled, per run, per ambient temperature, and the temperature law.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::fit::{fit_polach, fit_samples, fit_unprofiled, samples, PolachFit, Unprofiled};
use super::law::{Sample, DEFAULT_START};
use super::temperature::{fit_temperature_forms, FormChoice, TemperatureFit};
use crate::contact::polach::ContactPatch;
use crate::identify::dataset::RunTable;
use crate::identify::IdentifyError;

/// Polach fits of a campaign: per run, per ambient temperature, and k(T).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PolachReport {
    pub format: String,
    pub version: u32,
    /// The fixed contact patch: semi-axes a, b (m), shear modulus G (Pa), c11, c22, and the
    /// static wheel load Q (N) it was computed for.
    pub patch: [f64; 5],
    pub wheel_load_n: f64,
    /// All runs pooled: the parameters of the campaign's `polach` model file.
    pub pooled: Option<PolachFit>,
    /// Slip and speed ranges of the samples with slip (m/s): the model's domain.
    pub dv_range_mps: (f64, f64),
    pub v_range_mps: (f64, f64),
    pub per_run: Vec<PolachFit>,
    pub per_temperature: Vec<PolachFit>,
    /// The temperature law and the forms it was chosen from; absent with fewer than two
    /// temperatures (`temperature_note` says why).
    pub temperature: Option<TemperatureFit>,
    /// Why there is no temperature law: `temperature` absent, or its chosen form constant.
    pub temperature_note: Option<String>,
    /// The campaign generation that wrote the file (`campaign.json`'s), when a campaign did.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub generation: Option<String>,
    /// Which creepage the fits use, and why (absent in files written before the choice: each
    /// sample's speed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub creepage: Option<CreepageChoice>,
}

/// The creepage of a campaign's Polach fits: s = w/v at each sample's speed v (Polach's, seed
/// 004 eq. 2: the creep slope per m/s of slip falls as 1/v) or s = w/v_s at one fixed speed
/// v_s, the runs' median (the slip-velocity form: the same slope at every speed, as adhesion
/// curves measured over slip velocity show, seed 002 Fig. 8). Both have the same parameters;
/// the pooled fits (all runs, no temperature or speed law) decide by BIC with n_eff
/// ([`TemperatureCandidate`](super::TemperatureCandidate)'s criterion), Polach's unless the
/// fixed speed's is lower by more than 10.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CreepageChoice {
    pub chosen: Creepage,
    /// v_s of the slip-velocity form, m/s (the model file's `creepage_speed_mps` when chosen).
    pub fixed_speed_mps: f64,
    /// BIC and RMS residual of μ of the pooled fit with each: Polach's, then the fixed speed's
    /// (absent where the campaign's choice was refitted, in the model choice's folds).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bic: Option<[f64; 2]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rmse: Option<[f64; 2]>,
}

/// Where the creepage s = w/v_s is taken.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Creepage {
    /// At each sample's rolling speed (Polach's).
    RollingSpeed,
    /// At one fixed speed (the slip-velocity form).
    FixedSpeed,
}

impl CreepageChoice {
    /// The speed the creepage is taken at: `None` for each sample's own.
    pub fn speed(&self) -> Option<f64> {
        (self.chosen == Creepage::FixedSpeed).then_some(self.fixed_speed_mps)
    }
}

/// BIC must favour the fixed speed's creepage by more than this to replace Polach's, the
/// physical one: "very strong" evidence on Kass & Raftery's scale (JASA 90 (1995) 773–795).
const CREEPAGE_BIC_MARGIN: f64 = 10.0;

/// The creepage of the pooled fits `rolling` (each sample's speed) and `fixed` (`v_s`, m/s):
/// the fixed speed's where its BIC is lower by more than [`CREEPAGE_BIC_MARGIN`], else
/// Polach's. Both forms have the same five parameters, so both BICs count all five (a
/// parameter held for want of identification was still chosen by the data); one n_eff for
/// both, the smaller (the more autocorrelated residuals).
/// `None` where a BIC is not finite (a fit without residual or samples): Polach's stays.
fn choose_creepage(rolling: &PolachFit, fixed: &PolachFit, v_s: f64) -> Option<CreepageChoice> {
    let n_eff = rolling.effective_samples.min(fixed.effective_samples);
    let bic = |f: &PolachFit| n_eff * (f.rmse * f.rmse).ln() + 5.0 * n_eff.ln();
    let b = [bic(rolling), bic(fixed)];
    b.iter().all(|x| x.is_finite()).then(|| CreepageChoice {
        chosen: if b[0] - b[1] > CREEPAGE_BIC_MARGIN {
            Creepage::FixedSpeed
        } else {
            Creepage::RollingSpeed
        },
        fixed_speed_mps: v_s,
        bic: Some(b),
        rmse: Some([rolling.rmse, fixed.rmse]),
    })
}

/// Fits every run, every temperature group (with profile-likelihood intervals for the pooled
/// and per-temperature fits when `intervals`) and the temperature law. Runs that cannot be
/// fitted are skipped with their error in `notes`.
pub fn fit_campaign(
    tables: &[RunTable],
    patch: ContactPatch,
    q_n: f64,
    decimate: usize,
    degree: usize,
    intervals: bool,
) -> (PolachReport, Vec<String>) {
    let all: Vec<&RunTable> = tables.iter().collect();
    let v_ref = crate::identify::median_speed(tables);
    // The groups with Polach's creepage and, beside them, the pooled fit with the fixed
    // speed's; the groups again with that one where BIC prefers it.
    let (fixed, (mut fits, mut notes)) = rayon::join(
        || {
            // Only at a speed the creepage can be taken at (runs that barely move have none).
            (v_ref.is_finite() && v_ref > 0.0)
                .then(|| {
                    let s = fit_samples("all runs", &all, patch, q_n, decimate, Some(v_ref))?;
                    fit_unprofiled("all runs", &s, DEFAULT_START)
                })
                .and_then(Result::ok)
        },
        || fit_groups(tables, patch, q_n, decimate, intervals, None, None),
    );
    let creepage = match (&fits.pooled, &fixed) {
        (Some(r), Some(f)) => choose_creepage(r, &f.fit, v_ref),
        _ => None,
    };
    let speed = creepage.as_ref().and_then(CreepageChoice::speed);
    if speed.is_some() {
        // The pooled fit at that speed is made: only its profiles are left.
        (fits, notes) = fit_groups(
            tables,
            patch,
            q_n,
            decimate,
            intervals,
            speed,
            fixed.as_ref(),
        );
    }
    let law = match &fits.pooled {
        Some(p) => fit_temperature_forms(
            &all,
            patch,
            q_n,
            decimate,
            degree,
            p,
            &fits.per_temperature,
            v_ref,
            intervals,
            None,
            speed,
        ),
        None => Err(no_pooled_fit()),
    };
    let mut r = report(&all, patch, q_n, decimate, fits, law, notes);
    r.0.creepage = creepage;
    r
}

/// The lean fit of a model-choice fold: all runs pooled (no intervals) and the temperature
/// and speed form `form` refitted on them (no search, no per-run or per-temperature fits).
pub fn fit_campaign_form(
    tables: &[RunTable],
    patch: ContactPatch,
    q_n: f64,
    decimate: usize,
    form: FormChoice,
) -> (PolachReport, Vec<String>) {
    let all: Vec<&RunTable> = tables.iter().collect();
    let mut notes = Vec::new();
    let v_ref = crate::identify::median_speed(tables);
    let speed = form.fixed_creepage_speed.then_some(v_ref);
    let pooled = fit_pooled(&all, patch, q_n, decimate, false, speed)
        .map_err(|e| notes.push(e.to_string()))
        .ok();
    let law = match (&pooled, !form.has_law()) {
        (Some(_), true) => Err(IdentifyError::Data {
            what: "the campaign chose no temperature or speed law".into(),
            hint: "none needed".into(),
        }),
        (Some(p), false) => fit_temperature_forms(
            &all,
            patch,
            q_n,
            decimate,
            0,
            p,
            &[],
            v_ref,
            false,
            Some(form),
            speed,
        ),
        (None, _) => Err(no_pooled_fit()),
    };
    let fits = GroupFits {
        pooled,
        per_run: Vec::new(),
        per_temperature: Vec::new(),
    };
    let mut r = report(&all, patch, q_n, decimate, fits, law, notes);
    r.0.creepage = Some(CreepageChoice {
        chosen: if speed.is_some() {
            Creepage::FixedSpeed
        } else {
            Creepage::RollingSpeed
        },
        fixed_speed_mps: v_ref,
        bic: None,
        rmse: None,
    });
    r
}

/// All runs pooled from the default start, with the creepage at `speed` ([`fit_polach`]).
fn fit_pooled(
    all: &[&RunTable],
    patch: ContactPatch,
    q_n: f64,
    decimate: usize,
    intervals: bool,
    speed: Option<f64>,
) -> Result<PolachFit, IdentifyError> {
    fit_polach(
        "all runs",
        all,
        patch,
        q_n,
        decimate,
        DEFAULT_START,
        intervals,
        speed,
    )
}

fn no_pooled_fit() -> IdentifyError {
    IdentifyError::Data {
        what: "no pooled Polach fit".into(),
        hint: "see the notes above".into(),
    }
}

/// The report of a campaign's fits and its temperature law (or why there is none), with the
/// slip and speed ranges of the pooled samples.
fn report(
    all: &[&RunTable],
    patch: ContactPatch,
    q_n: f64,
    decimate: usize,
    fits: GroupFits,
    law: Result<TemperatureFit, IdentifyError>,
    mut notes: Vec<String>,
) -> (PolachReport, Vec<String>) {
    let pooled_samples = samples(all, q_n, decimate);
    let range = |f: fn(&Sample) -> f64| {
        pooled_samples
            .iter()
            .map(f)
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| {
                (lo.min(x), hi.max(x))
            })
    };
    let (temperature, temperature_note) = law_and_note(law, &mut notes);
    (
        PolachReport {
            format: "railgrip-polach-fit".into(),
            version: 3,
            patch: [patch.a_m, patch.b_m, patch.g_pa, patch.c11, patch.c22],
            wheel_load_n: q_n,
            pooled: fits.pooled,
            dv_range_mps: range(|s| s.dv),
            v_range_mps: range(|s| s.v),
            per_run: fits.per_run,
            per_temperature: fits.per_temperature,
            temperature,
            temperature_note,
            generation: None,
            creepage: None,
        },
        notes,
    )
}

/// The fits of a campaign's groups.
struct GroupFits {
    pooled: Option<PolachFit>,
    per_run: Vec<PolachFit>,
    per_temperature: Vec<PolachFit>,
}

/// All runs pooled, every run and every ambient temperature, fitted independently: in
/// parallel, results kept in group order; the groups that could not be fitted in the notes.
/// `pooled`: the pooled fit at this creepage when it is made already (its profiles are added
/// with `intervals`).
fn fit_groups(
    tables: &[RunTable],
    patch: ContactPatch,
    q_n: f64,
    decimate: usize,
    intervals: bool,
    creepage_speed: Option<f64>,
    pooled: Option<&Unprofiled>,
) -> (GroupFits, Vec<String>) {
    let start = DEFAULT_START;
    let all: Vec<&RunTable> = tables.iter().collect();
    let mut temps: Vec<f64> = tables
        .iter()
        .filter_map(|t| t.metadata.ambient_temperature_c)
        .collect();
    temps.sort_by(f64::total_cmp);
    temps.dedup();
    enum Group {
        Pooled,
        Run(usize),
        Temperature(f64),
    }
    let mut groups = vec![Group::Pooled];
    groups.extend((0..tables.len()).map(Group::Run));
    groups.extend(temps.iter().map(|t| Group::Temperature(*t)));
    // One fit of a group, the creepage as the campaign takes it.
    let fit = |name: &str, group: &[&RunTable], profile: bool| {
        fit_polach(
            name,
            group,
            patch,
            q_n,
            decimate,
            start,
            profile,
            creepage_speed,
        )
    };
    let fits: Vec<(&Group, Result<PolachFit, IdentifyError>)> = groups
        .par_iter()
        .map(|g| {
            let r = match g {
                Group::Pooled => match pooled {
                    Some(u) if intervals => {
                        fit_samples("all runs", &all, patch, q_n, decimate, creepage_speed)
                            .map(|s| u.finish(true, &s))
                    }
                    Some(u) => Ok(u.fit.clone()),
                    None => fit("all runs", &all, intervals),
                },
                Group::Run(i) => {
                    let t = &tables[*i];
                    fit(&t.name, &[t], false).map(|mut f| {
                        f.ambient_temperature_c = t.metadata.ambient_temperature_c;
                        f
                    })
                }
                Group::Temperature(temp) => {
                    let group: Vec<&RunTable> = tables
                        .iter()
                        .filter(|t| t.metadata.ambient_temperature_c == Some(*temp))
                        .collect();
                    fit(&format!("T = {temp} °C"), &group, intervals).map(|mut f| {
                        f.ambient_temperature_c = Some(*temp);
                        f
                    })
                }
            };
            (g, r)
        })
        .collect();
    let mut notes = Vec::new();
    let mut out = GroupFits {
        pooled: None,
        per_run: Vec::new(),
        per_temperature: Vec::new(),
    };
    for (g, r) in fits {
        match (g, r) {
            (Group::Pooled, Ok(f)) => out.pooled = Some(f),
            (Group::Run(_), Ok(f)) => out.per_run.push(f),
            (Group::Temperature(_), Ok(f)) => out.per_temperature.push(f),
            (Group::Run(i), Err(e)) => notes.push(format!("{}: {e}", tables[*i].name)),
            (_, Err(e)) => notes.push(e.to_string()),
        }
    }
    (out, notes)
}

/// The temperature law when there is one, and why there is none (no law, or the constant form
/// chosen); temperatures whose k was not identified go into `notes`.
fn law_and_note(
    law: Result<TemperatureFit, IdentifyError>,
    notes: &mut Vec<String>,
) -> (Option<TemperatureFit>, Option<String>) {
    match law {
        Ok(t) => {
            for e in &t.excluded {
                notes.push(format!("k(T) not identified at {e}"));
            }
            let note = (!t.has_law()).then(|| {
                let best_other = t
                    .candidates
                    .iter()
                    .filter(|c| c.mu0_degree + c.k_degree > 0 || c.speed_form.is_some())
                    .map(|c| c.bic - t.candidates[0].bic)
                    .fold(f64::INFINITY, f64::min);
                format!(
                    "the data prefer no temperature or speed dependence (BIC of the best other form {} above the constant's){}",
                    if best_other.is_finite() { format!("{best_other:.1}") } else { "—".into() },
                    if t.notes.is_empty() { String::new() } else { format!("; {}", t.notes.join("; ")) }
                )
            });
            (Some(t), note)
        }
        Err(e) => (None, Some(e.to_string())),
    }
}
