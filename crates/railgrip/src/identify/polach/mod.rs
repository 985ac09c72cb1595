//! Polach creep-force fits (seed 004 004_7d175079b70fb95b.txt eq. 1–3; Polach 2005) to the
//! estimated μ, and the temperature dependence k_A(T), k_S(T) across runs.
//!
//! Per sample, one wheel carries Q = N_i / 2 and the estimate μ_i = T_i / N_i is the wheel's
//! F/Q, so the model is μ̂ = polach(patch, params, Q, v, Δv, 0).f_x / Q (contact library,
//! creepage Δv/v, falling friction μ = μ0[(1 − A)e^(−BΔv) + A]). The patch (Hertz + Kalker at
//! the static wheel load, pipeline `[contact]`) is held fixed.
//!
//! Parameters are fitted by the same Levenberg–Marquardt solver as the network, on
//! unconstrained coordinates with bounds by reparametrisation (logistic, `law::LOWER`,
//! `law::UPPER`), with the analytic Jacobian (`law::law_lanes`, evaluated a block of samples at a
//! time on vector lanes by `block::LawBlock`). What the data cannot identify
//! is held and named ([`fit_polach`]); the estimated parameters get Wald standard errors
//! corrected for the residuals' autocorrelation (n_eff, [`crate::linalg::effective_samples`])
//! and profile-likelihood intervals ([`Profile`]).
//!
//! Temperature: per ambient temperature (run metadata `ambient_temperature_c`), one Polach fit
//! of the pooled runs; then the temperature law — μ0(T) (seed 004 Fig. 2: the adhesion level
//! moves with temperature), k_A(T), k_S(T) (seed 004 eq. 3), or both, of degrees up to
//! `train.temperature_degree` — fitted jointly over all samples and chosen by BIC
//! ([`fit_temperature_forms`]).

mod block;
mod campaign;
mod fit;
mod law;
mod problem;
mod profile;
mod temperature;
#[cfg(test)]
mod tests;

pub use campaign::{fit_campaign, fit_campaign_form, Creepage, CreepageChoice, PolachReport};
pub use fit::{fit_polach, PolachFit};
pub use law::{ParamStatus, DEFAULT_START, PARAMETERS};
pub use profile::{Profile, PROFILE_LIMIT};
pub use temperature::{
    fit_temperature_forms, k_identified, FormChoice, SpeedLaw, TemperatureCandidate, TemperatureFit,
};

/// Standard errors in files: NaN (held, not identifiable or not applicable) written as `null`
/// and read back as NaN (JSON has no NaN).
mod nan_as_null {
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    pub fn serialize<S: Serializer>(x: &[f64; 5], s: S) -> Result<S::Ok, S::Error> {
        x.map(|v| v.is_finite().then_some(v)).serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<[f64; 5], D::Error> {
        let v = <[Option<f64>; 5]>::deserialize(d)?;
        Ok(v.map(|x| x.unwrap_or(f64::NAN)))
    }
}

/// [`nan_as_null`] for a list of any length.
mod nan_as_null_vec {
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    pub fn serialize<S: Serializer>(x: &[f64], s: S) -> Result<S::Ok, S::Error> {
        x.iter()
            .map(|v| v.is_finite().then_some(*v))
            .collect::<Vec<_>>()
            .serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<f64>, D::Error> {
        let v = <Vec<Option<f64>>>::deserialize(d)?;
        Ok(v.into_iter().map(|x| x.unwrap_or(f64::NAN)).collect())
    }
}
