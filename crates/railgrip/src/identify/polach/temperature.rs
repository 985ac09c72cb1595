//! The temperature and speed law: every form μ0(T), k_A(T), k_S(T)/k_A(T) up to the
//! pipeline's degree (seed 004 eq. 3, Fig. 2), each with and without a speed law of the
//! adhesion level μ0 × g(v) (linear or quadratic in v, or Curtius–Kniffler's shape: level
//! falling with rolling speed, seed 002 Fig. 8, which Polach's law alone lacks), fitted
//! jointly over all samples and chosen by BIC with n_eff.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::fit::{samples, PolachFit};
use super::law::{solver_order, with_patch, ParamStatus, Sample};
use super::problem::temperature_nodes;
use super::problem::{basis_at, constant_nodes, fit_settings, profile_settings, solve};
use super::problem::{Group, Nodes, PolachProblem, SpeedBasis, MAX_NODES, SPEED};
use crate::contact::polach::{horner, ContactPatch};
use crate::identify::dataset::RunTable;
use crate::identify::IdentifyError;
use crate::linalg::effective_samples;

/// One temperature form the campaign fit tried, and how it fitted.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TemperatureCandidate {
    /// Degrees of μ0(T) and of k_A(T), k_S(T)/k_A(T) (0: constant).
    pub mu0_degree: usize,
    pub k_degree: usize,
    /// μ0's speed law: "polynomial 1", "polynomial 2", "polynomial 3", "curtius_kniffler";
    /// absent: none.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub speed_form: Option<String>,
    /// Free parameters (those the pooled fit held are not counted).
    pub parameters: usize,
    pub sse: f64,
    pub rmse: f64,
    /// AIC = n_eff ln(SSE/n) + 2p and BIC = n_eff ln(SSE/n) + p ln n_eff: the Gaussian
    /// log-likelihood of n residuals carries the information of n_eff independent ones
    /// (n_eff of the most flexible form's residuals, the same for every candidate).
    pub aic: f64,
    pub bic: f64,
    pub iterations: usize,
    pub stop_reason: String,
    /// Why the form cannot be used (its law leaves the valid domain), if so.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rejected: Option<String>,
}

impl TemperatureCandidate {
    /// "μ0(T) degree 1, k(T) constant" and the like.
    pub fn form(&self) -> String {
        with_speed(
            form_name(self.mu0_degree, self.k_degree),
            self.speed_form.as_deref(),
        )
    }
}

/// A form's name with its speed law.
fn with_speed(name: String, speed: Option<&str>) -> String {
    match speed {
        None => name,
        Some(f) => format!("{name}, μ0(v) {f}"),
    }
}

/// μ0's fitted speed law (`railgrip_model::polach::SpeedSpec` with its standard errors).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SpeedLaw {
    /// "polynomial" or "curtius_kniffler".
    pub form: String,
    pub coefficients: Vec<f64>,
    #[serde(with = "super::nan_as_null_vec")]
    pub standard_errors: Vec<f64>,
    /// v_ref (m/s): g(v_ref) = 1; the model file's reference speed.
    pub reference_speed_mps: f64,
    /// The samples' speeds (m/s); v is clamped to them.
    pub fitted_range_mps: (f64, f64),
    /// Profile-likelihood intervals of the coefficients (`speed_c1`, …) when the fits have
    /// intervals (`train.polach_intervals`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub profiles: Vec<super::profile::Profile>,
}

impl SpeedLaw {
    /// g(v) at `v` (m/s), as the model file's evaluator computes it.
    pub fn factor(&self, v: f64) -> f64 {
        self.spec().factor(self.reference_speed_mps, v)
    }

    /// As a model file's speed section.
    pub fn spec(&self) -> crate::model::polach::SpeedSpec {
        crate::model::polach::SpeedSpec {
            form: self.form.clone(),
            coefficients: self.coefficients.clone(),
            fitted_range_mps: [self.fitted_range_mps.0, self.fitted_range_mps.1],
        }
    }
}

pub(super) fn form_name(mu0_degree: usize, k_degree: usize) -> String {
    let part = |name: &str, d: usize| match d {
        0 => format!("{name} constant"),
        d => format!("{name} degree {d}"),
    };
    format!("{}, {}", part("μ0(T)", mu0_degree), part("k(T)", k_degree))
}

/// The temperature law of a campaign: the form chosen by BIC among μ0(T) and k_A(T), k_S(T)
/// of degrees 0 … `train.temperature_degree`, fitted jointly to every sample of the runs with
/// an ambient temperature (A and B shared), and the candidates it was chosen from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TemperatureFit {
    /// The chosen degrees (both 0: the data prefer no temperature dependence).
    pub mu0_degree: usize,
    pub k_degree: usize,
    /// The chosen speed law of μ0; absent: none (or none offered).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub speed: Option<SpeedLaw>,
    /// The chosen form's polynomials, ascending powers of T (°C).
    pub mu0: Vec<f64>,
    pub k_a: Vec<f64>,
    pub k_s: Vec<f64>,
    pub a_ratio: f64,
    pub b_s_per_m: f64,
    /// Standard errors of the parameters that do not depend on T (μ0, A, B, k_A, k_S order;
    /// null for those that do, or that the pooled fit held).
    #[serde(with = "super::nan_as_null")]
    pub se: [f64; 5],
    pub fitted_range_c: (f64, f64),
    /// Median temperature of the samples (°C): the model file's μ0, k_A, k_S are the law's
    /// values there (used when a caller gives no temperature).
    pub reference_temperature_c: f64,
    pub samples: usize,
    pub effective_samples: f64,
    /// `BIC`.
    pub criterion: String,
    pub candidates: Vec<TemperatureCandidate>,
    /// Per temperature: (T, μ0, k_A, k_S) of that temperature's own fit minus the law.
    pub residuals: Vec<(f64, f64, f64, f64)>,
    /// Temperatures whose own fit did not identify k_A and k_S (k(T) forms are offered only
    /// when two or more do), with why.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub excluded: Vec<String>,
    /// Forms not offered, and why.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub notes: Vec<String>,
    /// The fixed speed the creepage was taken at (m/s; the slip-velocity form); absent: each
    /// sample's speed (Polach's creepage).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub creepage_speed_mps: Option<f64>,
}

impl TemperatureFit {
    /// Whether anything depends on temperature or speed (a law is written).
    pub fn has_law(&self) -> bool {
        self.has_temperature_law() || self.speed.is_some()
    }
    /// Whether anything depends on temperature.
    pub fn has_temperature_law(&self) -> bool {
        self.mu0_degree > 0 || self.k_degree > 0
    }
    pub fn form(&self) -> String {
        with_speed(
            form_name(self.mu0_degree, self.k_degree),
            self.speed
                .as_ref()
                .map(|s| speed_name(&s.form, s.coefficients.len()))
                .as_deref(),
        )
    }
    /// (μ0, k_A, k_S) at T (°C, not clamped).
    pub fn at(&self, t_c: f64) -> (f64, f64, f64) {
        (
            horner(&self.mu0, t_c),
            horner(&self.k_a, t_c),
            horner(&self.k_s, t_c),
        )
    }
    /// As a model file's temperature section (μ0 coefficients only when μ0 depends on T).
    pub fn spec(&self) -> crate::model::polach::TemperatureSpec {
        crate::model::polach::TemperatureSpec {
            mu0: if self.mu0_degree > 0 {
                self.mu0.clone()
            } else {
                Vec::new()
            },
            k_a: self.k_a.clone(),
            k_s: self.k_s.clone(),
            fitted_range_c: [self.fitted_range_c.0, self.fitted_range_c.1],
        }
    }
}

/// A temperature and speed form by its degrees and speed law: the form a campaign chose, which
/// the model choice's folds refit (parameters only, no search) on their runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FormChoice {
    pub mu0_degree: usize,
    pub k_degree: usize,
    /// The speed law: (Curtius–Kniffler, terms); `None`: none.
    pub speed: Option<(bool, usize)>,
    /// The creepage taken at the runs' median speed (the slip-velocity form) rather than at
    /// each sample's speed.
    pub fixed_creepage_speed: bool,
}

impl FormChoice {
    /// Whether the form has a temperature or speed law.
    pub fn has_law(&self) -> bool {
        self.mu0_degree > 0 || self.k_degree > 0 || self.speed.is_some()
    }
}

impl TemperatureFit {
    /// The chosen form, to refit elsewhere.
    pub fn form_choice(&self) -> FormChoice {
        FormChoice {
            mu0_degree: self.mu0_degree,
            k_degree: self.k_degree,
            speed: self
                .speed
                .as_ref()
                .map(|s| (s.form == "curtius_kniffler", s.coefficients.len())),
            fixed_creepage_speed: self.creepage_speed_mps.is_some(),
        }
    }
}

/// The temperatures whose own Polach fit identified k_A and k_S, and those left out with why
/// (a value held because the data did not determine it says nothing about how k changes with
/// temperature; k_S/k_A at its bound leaves k_S = k_A or 0, as determined as k_A).
pub fn k_identified(fits: &[PolachFit]) -> (Vec<f64>, Vec<String>) {
    let mut kept = Vec::new();
    let mut excluded = Vec::new();
    for f in fits {
        let Some(t) = f.ambient_temperature_c else {
            continue;
        };
        let held: Vec<String> = [(3, "k_A"), (4, "k_S")]
            .iter()
            .filter(|(k, _)| match f.status[*k] {
                ParamStatus::Estimated => false,
                ParamStatus::AtBound => *k == 3,
                ParamStatus::NotIdentifiable => true,
            })
            .map(|(k, name)| format!("{name} {}", f.status[*k].text()))
            .collect();
        if held.is_empty() {
            kept.push(t);
        } else {
            excluded.push(format!("T = {t} °C ({})", held.join(", ")));
        }
    }
    (kept, excluded)
}

/// The polynomial (ascending powers) through (nodes[j], values[j]): Σ_j values[j] L_j(t),
/// each L_j expanded as Π_{m≠j} (t − t_m)/(t_j − t_m).
pub(super) fn monomials(nodes: &[f64], values: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; nodes.len()];
    for (j, tj) in nodes.iter().enumerate() {
        let mut poly = vec![values[j]];
        for (m, tm) in nodes.iter().enumerate().filter(|(m, _)| *m != j) {
            let _ = m;
            let scale = 1.0 / (tj - tm);
            let mut next = vec![0.0; poly.len() + 1];
            for (p, c) in poly.iter().enumerate() {
                next[p + 1] += c * scale;
                next[p] -= c * tm * scale;
            }
            poly = next;
        }
        for (o, c) in out.iter_mut().zip(&poly) {
            *o += c;
        }
    }
    out
}

/// Product of two polynomials (ascending powers).
pub(super) fn poly_mul(a: &[f64], b: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; a.len() + b.len() - 1];
    for (i, x) in a.iter().enumerate() {
        for (j, y) in b.iter().enumerate() {
            out[i + j] += x * y;
        }
    }
    out
}

/// A note when the samples' slip coverage changes monotonically with temperature: the median
/// slip of each temperature group, ordered by temperature, strictly rising or falling over three
/// or more temperatures by more than 20 %. A law family that does not fit the data exactly then
/// fits different slip ranges with different parameters, and a temperature law can stand for
/// the coverage (e.g. a campaign that brakes harder in the cold) — the data cannot tell them
/// apart (measured on the foreign `table` law, docs/training.md#temperature-law).
pub(super) fn coverage_note(
    s: &[Sample],
    ranges: &[(f64, std::ops::Range<usize>)],
) -> Option<String> {
    if ranges.len() < 3 {
        return None;
    }
    let medians: Vec<f64> = ranges
        .iter()
        .map(|(_, r)| {
            let mut dv: Vec<f64> = s[r.clone()].iter().map(|x| x.dv).collect();
            dv.sort_by(f64::total_cmp);
            dv.get(dv.len() / 2).copied().unwrap_or(f64::NAN)
        })
        .collect();
    let rising = medians.windows(2).all(|w| w[1] > w[0]);
    let falling = medians.windows(2).all(|w| w[1] < w[0]);
    let (first, last) = (medians[0], medians[medians.len() - 1]);
    if !(rising || falling) || (first.max(last) / first.min(last)) < 1.2 {
        return None;
    }
    Some(format!(
        "the runs' slip coverage changes with temperature (median Δv {:.2} m/s at {} °C to {:.2} m/s at {} °C): a temperature law here may stand for the slip range each temperature's runs cover rather than for the temperature; brake at equal demand across temperatures (or add runs) to tell them apart",
        first,
        ranges[0].0,
        last,
        ranges[ranges.len() - 1].0
    ))
}

/// One candidate's fit: its record, the law's polynomials (μ0, k_A, k_S), A, B, and the
/// standard errors of its constant parameters.
pub(super) struct FormFit {
    pub(super) record: TemperatureCandidate,
    pub(super) mu0: Vec<f64>,
    pub(super) k_a: Vec<f64>,
    pub(super) k_s: Vec<f64>,
    pub(super) a_ratio: f64,
    pub(super) b_s_per_m: f64,
    pub(super) se: [f64; 5],
    pub(super) speed: Option<SpeedLaw>,
    pub(super) residuals: Vec<f64>,
    /// The solution's node values (the start of the form's speed-law fits).
    pub(super) nodes: Nodes,
    /// SSE at the solution and σ² n/n_eff (the profile statistic's scale).
    pub(super) sse: f64,
    pub(super) scale: f64,
}

/// Fits the temperature law of a campaign: the candidate forms μ0(T) of degree d_μ and k_A(T),
/// ρ(T) = k_S/k_A of degree d_k (d ≤ min(`degree`, temperatures − 1); A and B constant), each
/// jointly over all samples of the runs with `ambient_temperature_c`, each parameter's law as
/// its values at evenly spaced nodes over the range (Lagrange basis; logistic bounds at the
/// nodes, clamped between them), from the pooled fit's values, with the parameters the pooled
/// fit held still held. The form with the least BIC (n_eff-corrected, see
/// [`TemperatureCandidate`]) whose law stays in the valid domain over the range
/// (0 < μ0 ≤ 1.5, 0 < k_S ≤ k_A ≤ 1) is chosen. k forms are offered only when two or more
/// temperatures' own fits identified k_A and k_S ([`k_identified`]), μ0 forms only when the
/// pooled fit identified μ0. With `intervals`, the chosen speed law's coefficients get
/// profile-likelihood intervals.
#[allow(clippy::too_many_arguments)]
pub fn fit_temperature_forms(
    tables: &[&RunTable],
    patch: ContactPatch,
    q_n: f64,
    decimate: usize,
    degree: usize,
    pooled: &PolachFit,
    per_temperature: &[PolachFit],
    v_ref: f64,
    intervals: bool,
    pinned: Option<FormChoice>,
    creepage_speed: Option<f64>,
) -> Result<TemperatureFit, IdentifyError> {
    let g = Grouped::of(tables, patch, q_n, decimate, creepage_speed)?;
    let (lo, hi) = g.range;
    let offered = match pinned {
        None => Offered::of(&g, degree, pooled, per_temperature, v_ref),
        Some(f) => Offered::pinned(&g, f, v_ref),
    };
    if g.temps.len() < 2 && offered.speeds.len() == 1 {
        let why = offered
            .notes
            .iter()
            .find(|n| n.starts_with("μ0(v) forms not offered"))
            .map_or("", String::as_str);
        return Err(IdentifyError::Data {
            what: format!(
                "a temperature law needs runs at two or more ambient temperatures; found 1 ({why})"
            ),
            hint: "give runs at several ambient temperatures with ambient_temperature_c in their metadata, or from several initial speeds".into(),
        });
    }
    let x0 = solver_order(&pooled.params());
    let held = |i: usize| pooled.status[i] != ParamStatus::Estimated;
    let fixed: [Option<f64>; 5] = std::array::from_fn(|i| held(i).then_some(x0[i]));
    let mut fits = fit_all_forms(&g, &offered, fixed, &x0)?;
    let n_eff = score_forms(&mut fits, g.samples.len(), g.range);
    // A pinned form with a speed law: that fit (the last), not the one without — unless its
    // law is refused on these samples; then the form without (the law still stands on its
    // temperature form).
    let valid = |i: &usize| fits[*i].record.rejected.is_none();
    let pinned_speed = pinned.is_some_and(|f| f.speed.is_some()) && fits.len() > 1;
    let by_bic = |from: usize| {
        (from..fits.len())
            .filter(valid)
            .min_by(|a, b| fits[*a].record.bic.total_cmp(&fits[*b].record.bic))
    };
    let best = by_bic(usize::from(pinned_speed))
        .or_else(|| if pinned_speed { by_bic(0) } else { None })
        .ok_or_else(|| IdentifyError::Data {
            what: format!(
                "every temperature and speed form leaves the valid domain of Polach's law (the constant form: {})",
                fits[0].record.rejected.as_deref().unwrap_or("–")
            ),
            hint: "lower train.temperature_degree".into(),
        })?;
    let chosen = &fits[best];
    let mut speed = chosen.speed.clone();
    if let (Some(s), true) = (&mut speed, intervals) {
        s.profiles = speed_profiles(&g, chosen, fixed);
    }
    let mut law = TemperatureFit {
        mu0_degree: chosen.record.mu0_degree,
        k_degree: chosen.record.k_degree,
        speed,
        mu0: chosen.mu0.clone(),
        k_a: chosen.k_a.clone(),
        k_s: chosen.k_s.clone(),
        a_ratio: chosen.a_ratio,
        b_s_per_m: chosen.b_s_per_m,
        se: chosen.se,
        fitted_range_c: (lo, hi),
        reference_temperature_c: g.reference_c,
        samples: g.samples.len(),
        effective_samples: n_eff,
        criterion: "BIC".into(),
        candidates: fits.into_iter().map(|f| f.record).collect(),
        residuals: Vec::new(),
        excluded: offered.excluded,
        notes: offered.notes,
        creepage_speed_mps: creepage_speed,
    };
    law.residuals = per_temperature
        .iter()
        .filter(|_| law.has_temperature_law())
        .filter_map(|f| {
            let t = f.ambient_temperature_c?;
            let (m, a, k) = law.at(t);
            Some((t, f.mu0 - m, f.k_a - a, f.k_s - k))
        })
        .collect();
    Ok(law)
}

/// The samples with slip of the runs with an ambient temperature, grouped by temperature.
struct Grouped {
    /// The distinct temperatures, ascending, °C.
    temps: Vec<f64>,
    /// Lowest and highest temperature, °C.
    range: (f64, f64),
    /// The samples (with their patch term), one contiguous range per temperature.
    samples: Vec<Sample>,
    ranges: Vec<(f64, std::ops::Range<usize>)>,
    /// The samples' median temperature, °C.
    reference_c: f64,
    /// Lowest and highest speed of the samples, m/s.
    speeds: (f64, f64),
    /// Runs without an ambient temperature (left out of these samples).
    without_temperature: usize,
}

impl Grouped {
    fn of(
        tables: &[&RunTable],
        patch: ContactPatch,
        q_n: f64,
        decimate: usize,
        creepage_speed: Option<f64>,
    ) -> Result<Grouped, IdentifyError> {
        let mut temps: Vec<f64> = tables
            .iter()
            .filter_map(|t| t.metadata.ambient_temperature_c)
            .collect();
        temps.sort_by(f64::total_cmp);
        temps.dedup();
        if temps.is_empty() {
            return Err(IdentifyError::Data {
                what:
                    "a temperature or speed law needs runs with an ambient temperature; found none"
                        .into(),
                hint: "give the runs ambient_temperature_c in their metadata".into(),
            });
        }
        let (lo, hi) = (temps[0], temps[temps.len() - 1]);
        let mut s = Vec::new();
        let mut ranges = Vec::new();
        for t in &temps {
            let at: Vec<&RunTable> = tables
                .iter()
                .copied()
                .filter(|r| r.metadata.ambient_temperature_c == Some(*t))
                .collect();
            let from = s.len();
            s.extend(samples(&at, q_n, decimate));
            ranges.push((*t, from..s.len()));
        }
        if s.len() < 20 {
            return Err(IdentifyError::Data {
                what: format!("only {} samples with slip for the temperature law", s.len()),
                hint: "fit on braking runs with wheel slip".into(),
            });
        }
        let s = with_patch(s, &patch, creepage_speed);
        // The samples' median temperature (groups are in ascending temperature).
        let mut seen = 0;
        let reference_c = ranges
            .iter()
            .find(|(_, r)| {
                seen += r.len();
                2 * seen > s.len()
            })
            .map_or(lo, |(t, _)| *t);
        let speeds = s
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
                (a.min(x.v), b.max(x.v))
            });
        Ok(Grouped {
            temps,
            range: (lo, hi),
            samples: s,
            ranges,
            reference_c,
            speeds,
            without_temperature: tables
                .iter()
                .filter(|t| t.metadata.ambient_temperature_c.is_none())
                .count(),
        })
    }
}

/// The highest degrees of μ0(T) and of k(T) the data allow, the temperatures whose k_A, k_S
/// were not identified, and notes on what was not offered and why.
struct Offered {
    mu_top: usize,
    k_top: usize,
    /// Only the form of these degrees (a pinned form), not every one up to the tops.
    only: bool,
    /// The speed laws to try: None (no speed law) first.
    speeds: Vec<Option<SpeedBasis>>,
    excluded: Vec<String>,
    notes: Vec<String>,
}

/// Speed laws are offered when the samples span at least this ratio of speeds (highest over
/// lowest) and this many m/s: a level's speed dependence needs a range to be told from noise.
const SPEED_SPAN_RATIO: f64 = 1.5;
const SPEED_SPAN_MPS: f64 = 10.0;

/// A speed form's name in the candidates' table.
fn speed_name(form: &str, terms: usize) -> String {
    if form == "polynomial" {
        format!("polynomial {terms}")
    } else {
        form.to_string()
    }
}

impl Offered {
    fn of(
        g: &Grouped,
        degree: usize,
        pooled: &PolachFit,
        per_temperature: &[PolachFit],
        v_ref: f64,
    ) -> Self {
        let mut notes = Vec::new();
        let held = |i: usize| pooled.status[i] != ParamStatus::Estimated;
        let top = degree.min(g.temps.len() - 1).min(MAX_NODES - 1);
        let (vlo, vhi) = g.speeds;
        let mut speeds = vec![None];
        if held(0) {
            notes.push("μ0(v) forms not offered: the pooled fit holds μ0".into());
        } else if g.without_temperature > 0 {
            notes.push(format!(
                "μ0(v) forms not offered: {} run(s) have no ambient temperature (the speed law is fitted with the temperature forms, on the runs that have one, and must cover the model's whole speed range)",
                g.without_temperature
            ));
        } else if vhi < SPEED_SPAN_RATIO * vlo || vhi - vlo < SPEED_SPAN_MPS {
            notes.push(format!(
                "μ0(v) forms not offered: the samples span {vlo:.1} … {vhi:.1} m/s (a speed law needs ×{SPEED_SPAN_RATIO} and {SPEED_SPAN_MPS} m/s)"
            ));
        } else {
            let basis = |ck: bool, terms: usize| SpeedBasis {
                curtius_kniffler: ck,
                terms,
                v_ref,
                range: g.speeds,
            };
            speeds.extend([
                Some(basis(false, 1)),
                Some(basis(true, 1)),
                Some(basis(false, 2)),
                Some(basis(false, 3)),
            ]);
        }
        let (k_temps, excluded) = k_identified(per_temperature);
        let k_top = if held(3) || held(4) {
            notes.push(format!(
                "k(T) forms not offered: the pooled fit holds {}",
                if held(3) { "k_A" } else { "k_S/k_A" }
            ));
            0
        } else if k_temps.len() < 2 {
            notes.push(format!(
                "k(T) forms not offered: k_A and k_S are identified at {} of the temperatures (two or more needed); left out: {}",
                k_temps.len(),
                excluded.join("; ")
            ));
            0
        } else {
            top.min(k_temps.len() - 1)
        };
        let mu_top = if held(0) {
            notes.push("μ0(T) forms not offered: the pooled fit holds μ0".into());
            0
        } else {
            top
        };
        if g.temps.len() == 1 {
            notes.push("one ambient temperature: no temperature forms".into());
        } else if top == 0 {
            notes.push("train.temperature_degree = 0: only the constant form".into());
        }
        if let Some(n) = coverage_note(&g.samples, &g.ranges) {
            notes.push(n);
        }
        Offered {
            mu_top,
            k_top,
            only: false,
            speeds,
            excluded,
            notes,
        }
    }

    /// Exactly the form `f` (its degrees capped at the temperatures − 1 of these samples; its
    /// speed law over these samples' speeds).
    fn pinned(g: &Grouped, f: FormChoice, v_ref: f64) -> Self {
        let top = (g.temps.len() - 1).min(MAX_NODES - 1);
        let mut speeds = vec![None];
        if let Some((ck, terms)) = f.speed {
            speeds.push(Some(SpeedBasis {
                curtius_kniffler: ck,
                terms,
                v_ref,
                range: g.speeds,
            }));
        }
        Offered {
            mu_top: f.mu0_degree.min(top),
            k_top: f.k_degree.min(top),
            only: true,
            speeds,
            excluded: Vec::new(),
            notes: Vec::new(),
        }
    }
}

/// Temperature forms with the least BIC (without a speed law) that the speed laws are fitted
/// on: each speed law is fitted on these, warm-started from their solutions.
const SPEED_ON_T_FORMS: usize = 3;

/// Every candidate: the temperature forms without a speed law, from the pooled fit's values;
/// then, when speed laws are offered, each speed law on the [`SPEED_ON_T_FORMS`] temperature
/// forms with the least BIC so far, warm-started from their solutions (a speed law changes the
/// level, rarely which temperature form fits best; the search costs 9 + 12 fits instead of
/// 45 at degree 2). Ordered by temperature form, then speed law.
fn fit_all_forms(
    g: &Grouped,
    offered: &Offered,
    fixed: [Option<f64>; 5],
    x0: &[f64; 5],
) -> Result<Vec<FormFit>, IdentifyError> {
    let t_forms: Vec<(usize, usize)> = if offered.only {
        vec![(offered.mu_top, offered.k_top)]
    } else {
        (0..=offered.mu_top)
            .flat_map(|dm| (0..=offered.k_top).map(move |dk| (dm, dk)))
            .collect()
    };
    let start = constant_nodes(x0);
    let base: Vec<FormFit> = t_forms
        .par_iter()
        .map(|&(dm, dk)| fit_form(g, [dm, 0, 0, dk, dk], None, fixed, &start))
        .collect::<Result<_, _>>()?;
    let speeds: Vec<SpeedBasis> = offered.speeds.iter().flatten().copied().collect();
    if speeds.is_empty() {
        return Ok(base);
    }
    // The provisional BIC of the temperature forms (n_eff of the most flexible one).
    let n = g.samples.len() as f64;
    let n_eff = effective_samples(&most_flexible(&base).residuals).max(1.0);
    let bic = |f: &FormFit| information(f.record.sse, n, f.record.parameters, n_eff).1;
    // The valid temperature forms by BIC (a form whose law is refused cannot be chosen).
    let mut order: Vec<usize> = (0..base.len())
        .filter(|i| law_rejection(&base[*i], g.range).is_none())
        .collect();
    order.sort_by(|a, b| bic(&base[*a]).total_cmp(&bic(&base[*b])));
    order.truncate(SPEED_ON_T_FORMS);
    let jobs: Vec<(usize, SpeedBasis)> = order
        .iter()
        .flat_map(|&i| speeds.iter().map(move |sp| (i, *sp)))
        .collect();
    let with_speed: Vec<(usize, FormFit)> = jobs
        .par_iter()
        .map(|&(i, sp)| {
            let r = &base[i].record;
            let degrees = [r.mu0_degree, 0, 0, r.k_degree, r.k_degree];
            fit_form(g, degrees, Some(sp), fixed, &base[i].nodes).map(|f| (i, f))
        })
        .collect::<Result<_, _>>()?;
    // Each temperature form followed by its speed laws (a stable sort keeps their order).
    let mut with_speed = with_speed;
    with_speed.sort_by_key(|(i, _)| *i);
    let mut extra = with_speed.into_iter().peekable();
    let mut out = Vec::new();
    for (i, b) in base.into_iter().enumerate() {
        out.push(b);
        while let Some((_, f)) = extra.next_if(|(j, _)| *j == i) {
            out.push(f);
        }
    }
    Ok(out)
}

/// AIC = n_eff ln(SSE/n) + 2p and BIC = n_eff ln(SSE/n) + p ln n_eff of a fit with `p` free
/// parameters and `sse` over `n` samples (see [`TemperatureCandidate`]).
fn information(sse: f64, n: f64, p: usize, n_eff: f64) -> (f64, f64) {
    let fit_term = n_eff * (sse / n).ln();
    (fit_term + 2.0 * p as f64, fit_term + p as f64 * n_eff.ln())
}

/// The fit with the most free parameters (the last of them).
fn most_flexible(fits: &[FormFit]) -> &FormFit {
    // `max_by_key` returns the last of equal maxima.
    fits.iter()
        .max_by_key(|f| f.record.parameters)
        .expect("at least the constant form")
}

/// Why a form's temperature law cannot be written (the model reader's own check), if so; the
/// constant form writes no law and is never refused for it.
fn law_rejection(f: &FormFit, (lo, hi): (f64, f64)) -> Option<String> {
    if f.record.mu0_degree == 0 && f.record.k_degree == 0 {
        return None;
    }
    let spec = crate::model::polach::TemperatureSpec {
        mu0: f.mu0.clone(),
        k_a: f.k_a.clone(),
        k_s: f.k_s.clone(),
        fitted_range_c: [lo, hi],
    };
    crate::model::polach::check_law(&spec, f.mu0[0])
        .err()
        .map(|e| e.to_string())
}

/// The least-squares problem of one form over every temperature group, `fixed` parameters and
/// `speed_held` coefficients held.
fn form_problem<'a>(
    g: &'a Grouped,
    degrees: [usize; 5],
    speed: Option<SpeedBasis>,
    fixed: [Option<f64>; 5],
    speed_held: [Option<f64>; 3],
) -> PolachProblem<'a> {
    let (lo, hi) = g.range;
    let groups = g
        .ranges
        .iter()
        .map(|(t, r)| Group {
            range: r.clone(),
            basis: basis_at(degrees, lo, hi, *t),
        })
        .collect();
    let degrees_free: [usize; 5] =
        std::array::from_fn(|i| if fixed[i].is_some() { 0 } else { degrees[i] });
    let problem = PolachProblem::new(&g.samples, groups, degrees_free, fixed, None);
    match speed {
        Some(b) => problem.with_speed(b, speed_held),
        None => problem,
    }
}

/// The profile likelihood of each coefficient of the chosen form's speed law
/// ([`super::profile::Profile`], the same statistic and limits as the Polach fits' intervals):
/// at values c_j ± z se_j the rest of the form refitted, warm-started from the previous point.
fn speed_profiles(
    g: &Grouped,
    chosen: &FormFit,
    fixed: [Option<f64>; 5],
) -> Vec<super::profile::Profile> {
    use super::profile::{Profile, Side, PROFILE_LIMIT, PROFILE_STEPS};
    let Some(law) = &chosen.speed else {
        return Vec::new();
    };
    let basis = SpeedBasis {
        curtius_kniffler: law.form == "curtius_kniffler",
        terms: law.coefficients.len(),
        v_ref: law.reference_speed_mps,
        range: law.fitted_range_mps,
    };
    let r = &chosen.record;
    let degrees = [r.mu0_degree, 0, 0, r.k_degree, r.k_degree];
    let sides: Vec<(usize, f64)> = (0..basis.terms)
        .filter(|j| law.standard_errors[*j].is_finite() && law.standard_errors[*j] > 0.0)
        .flat_map(|j| [(j, -1.0), (j, 1.0)])
        .collect();
    let walked: Vec<(usize, Side)> = sides
        .par_iter()
        .map(|&(j, dir)| {
            let (c0, se) = (law.coefficients[j], law.standard_errors[j]);
            let mut warm = chosen.nodes;
            let (mut pts, mut prev): (Vec<(f64, f64)>, (f64, f64)) = (Vec::new(), (c0, 0.0));
            for z in PROFILE_STEPS {
                let at = c0 + dir * z * se;
                let mut held = [None; 3];
                held[j] = Some(at);
                let problem = form_problem(g, degrees, Some(basis), fixed, held);
                let Ok((problem, theta, _, _)) =
                    solve("speed-law profile", problem, &warm, profile_settings())
                else {
                    return (j, (pts, None));
                };
                warm = problem.nodes(&theta).0;
                let stat = ((problem.sse_nodes(&warm) - chosen.sse) / chosen.scale).max(0.0);
                pts.push((at, stat));
                if stat > PROFILE_LIMIT {
                    let (z0, z1) = (prev.1.sqrt(), stat.sqrt());
                    let t = ((PROFILE_LIMIT.sqrt() - z0) / (z1 - z0)).clamp(0.0, 1.0);
                    return (j, (pts, Some(prev.0 + t * (at - prev.0))));
                }
                prev = (at, stat);
            }
            (j, (pts, None))
        })
        .collect();
    // Each side's first point tells which side it is.
    let side = |j: usize, below: bool| {
        walked
            .iter()
            .find(|(k, (pts, _))| {
                *k == j
                    && pts
                        .first()
                        .is_some_and(|x| (x.0 < law.coefficients[j]) == below)
            })
            .map(|(_, s)| s)
    };
    (0..basis.terms)
        .filter_map(|j| {
            let (lo_pts, lower) = side(j, true)?;
            let (hi_pts, upper) = side(j, false)?;
            let mut points: Vec<(f64, f64)> = lo_pts.iter().rev().copied().collect();
            points.push((law.coefficients[j], 0.0));
            points.extend(hi_pts.iter().copied());
            Some(Profile {
                parameter: format!("speed_c{}", j + 1),
                estimate: law.coefficients[j],
                lower: *lower,
                upper: *upper,
                points,
            })
        })
        .collect()
}

/// One form (degrees of μ0, A, B, k_A, ρ, optionally μ0's speed law) fitted jointly over every
/// temperature group from node values `start`, with `fixed` held; its polynomials (ascending
/// powers of T) and the standard errors of its constant parameters.
fn fit_form(
    g: &Grouped,
    degrees: [usize; 5],
    speed: Option<SpeedBasis>,
    fixed: [Option<f64>; 5],
    start: &Nodes,
) -> Result<FormFit, IdentifyError> {
    let (lo, hi) = g.range;
    let (dm, dk) = (degrees[0], degrees[3]);
    let nodes: Vec<Vec<f64>> = degrees
        .iter()
        .map(|&d| temperature_nodes(d, lo, hi))
        .collect();
    let problem = form_problem(g, degrees, speed, fixed, [None; 3]);
    let speed_label = speed.map(|b| speed_name(b.form(), b.terms));
    let (problem, theta, its, stop) = solve(
        &with_speed(form_name(dm, dk), speed_label.as_deref()),
        problem,
        start,
        fit_settings(),
    )?;
    let (v, _) = problem.nodes(&theta);
    let cov = problem.covariance(&theta);
    let value = |i: usize| -> Vec<f64> {
        match fixed[i] {
            Some(f) => vec![f],
            None => monomials(&nodes[i], &v[i][..=degrees[i]]),
        }
    };
    let k = problem.free.len();
    let mut se = [f64::NAN; 5];
    let mut speed_se = Vec::new();
    for (c, co) in problem.free.iter().enumerate() {
        let sd = cov.cov.as_ref().map_or(f64::NAN, |m| m[c * k + c].sqrt());
        if co.param == SPEED {
            speed_se.push(sd);
        } else if degrees[co.param] == 0 {
            se[co.param] = sd;
        }
    }
    let speed_law = speed.map(|b| SpeedLaw {
        form: b.form().into(),
        coefficients: v[SPEED][..b.terms].to_vec(),
        standard_errors: speed_se,
        reference_speed_mps: b.v_ref,
        fitted_range_mps: b.range,
        profiles: Vec::new(),
    });
    let (ka, rho) = (value(3), value(4));
    if degrees[3] == 0 && fixed[3].is_none() && fixed[4].is_none() {
        let pos = |p: usize| problem.free.iter().position(|c| c.param == p);
        if let (Some(a), Some(b), Some(m)) = (pos(3), pos(4), &cov.cov) {
            se[4] = (rho[0] * rho[0] * m[a * k + a]
                + ka[0] * ka[0] * m[b * k + b]
                + 2.0 * ka[0] * rho[0] * m[a * k + b])
                .sqrt();
        }
    } else {
        se[4] = f64::NAN;
    }
    Ok(FormFit {
        record: TemperatureCandidate {
            mu0_degree: dm,
            k_degree: dk,
            speed_form: speed_label,
            parameters: k,
            sse: cov.sse,
            rmse: (cov.sse / g.samples.len() as f64).sqrt(),
            aic: f64::NAN,
            bic: f64::NAN,
            iterations: its,
            stop_reason: stop.text().into(),
            rejected: None,
        },
        mu0: value(0),
        k_s: poly_mul(&ka, &rho),
        k_a: ka,
        a_ratio: value(1)[0],
        b_s_per_m: value(2)[0],
        se,
        speed: speed_law,
        residuals: cov.residuals,
        nodes: v,
        sse: cov.sse,
        scale: cov.scale,
    })
}

/// Each form's AIC and BIC with n_eff of the most flexible form's residuals (the most free
/// parameters, the last of them; closest
/// to the noise alone — a form that misses a temperature trend leaves residuals correlated over
/// whole runs, whose n_eff would hide the very trend), and the forms whose law leaves the valid
/// domain over `range` rejected by the model reader's own check. Returns n_eff.
fn score_forms(fits: &mut [FormFit], samples: usize, (lo, hi): (f64, f64)) -> f64 {
    let n = samples as f64;
    let n_eff = effective_samples(&most_flexible(fits).residuals).max(1.0);
    for f in fits.iter_mut() {
        // A law is written only for what depends on temperature or speed (the constant form's
        // values are the pooled fit's, checked as the model file is).
        let rejected = law_rejection(f, (lo, hi)).or_else(|| {
            let sp = f.speed.as_ref()?;
            // The largest μ0 over the temperature range, as the model file's check takes it.
            let law = crate::model::polach::TemperatureSpec {
                mu0: f.mu0.clone(),
                k_a: Vec::new(),
                k_s: Vec::new(),
                fitted_range_c: [lo, hi],
            };
            let mu0_max = crate::model::polach::largest_mu0(f.mu0[0], Some(&law));
            crate::model::polach::check_speed_law(&sp.spec(), sp.reference_speed_mps, mu0_max)
                .err()
                .map(|e| e.to_string())
        });
        let c = &mut f.record;
        (c.aic, c.bic) = information(c.sse, n, c.parameters, n_eff);
        c.rejected = rejected;
        f.residuals = Vec::new();
    }
    n_eff
}
