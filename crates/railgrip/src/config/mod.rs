//! The pipeline file: raw serde types ([`raw`]), checked into validated types ([`Pipeline`]),
//! one file per section (raw type, validated type, key table and check side by side):
//! [`vehicle`], [`ingest`], [`filters`], [`estimate`], [`contact`], [`train`]. [`rule`] holds
//! the key tables' types and the [`rule::Checker`] shared with scene files.
//!
//! Stages only ever see validated types. Every check names the key, the value found, the
//! allowed range and the default, e.g.
//! `ingest.max_gap_ms = -5: must be > 2.3981 ms and <= 10000 ms (default 50 ms); ...`.
//! The options are documented in docs/pipeline.md, rendered from the key tables
//! (a test keeps the two equal).

pub mod calibrated;
pub mod contact;
pub mod estimate;
pub mod filters;
pub mod ingest;
pub mod rule;
pub mod train;
pub mod vehicle;

use std::path::Path;

pub use contact::ContactConfig;
pub use estimate::{CalibrationSource, EstimateConfig, Phase};
pub use filters::{DespikeConfig, FilterConfig, FilterMode};
pub use ingest::{CsvColumn, IngestConfig, McapField, Plausibility, PlausibilityAction};
pub(crate) use rule::Checker;
pub use rule::Key;
pub use train::{
    default_support_cells, ModelChoice, Optimizer, SplitConfig, TrainConfig, Trainer,
    DEFAULT_AUDIT_MU_MAX, DEFAULT_SUPPORT_MIN_SAMPLES, TRAINBR_MU,
};
pub use vehicle::Vehicle;

/// The embedded default pipeline (`pipelines/uic_z1.toml`).
pub const DEFAULT_PIPELINE_TOML: &str = include_str!("../../../../pipelines/uic_z1.toml");
/// How the embedded default is named in messages and provenance.
pub const DEFAULT_PIPELINE_NAME: &str = "<embedded pipelines/uic_z1.toml>";

/// A pipeline file that could not be read or does not pass its checks.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    #[error(
        "{file}: cannot read the pipeline file: {source}. Hint: check the path given to --pipeline"
    )]
    Read {
        file: String,
        #[source]
        source: std::io::Error,
    },
    #[error("{file}: not a valid pipeline file: {message}")]
    Syntax { file: String, message: String },
    #[error("{file}: {key} = {value}: {rule}")]
    Invalid {
        file: String,
        key: String,
        value: String,
        rule: String,
    },
    #[error("{file}: {key} is missing: {rule}")]
    Missing {
        file: String,
        key: String,
        rule: String,
    },
}

/// Raw serde types: exactly the TOML's shape, every field optional so that checks, not serde,
/// produce the messages.
pub mod raw {
    use serde::Deserialize;

    pub use super::contact::raw::Contact;
    pub use super::estimate::raw::Estimate;
    pub use super::filters::raw::Filters;
    pub use super::ingest::raw::{
        CsvColumn, CsvMapping, Ingest, McapField, McapMapping, Plausibility,
    };
    pub use super::train::raw::Train;
    pub use super::vehicle::raw::Vehicle;

    #[derive(Debug, Default, Deserialize)]
    #[serde(deny_unknown_fields)]
    pub struct Pipeline {
        pub vehicle: Option<Vehicle>,
        #[serde(default)]
        pub ingest: Ingest,
        #[serde(default)]
        pub filters: Filters,
        #[serde(default)]
        pub estimate: Estimate,
        #[serde(default)]
        pub contact: Contact,
        #[serde(default)]
        pub train: Train,
    }
}

/// The pipeline file's sections and their key tables, in the order of the documented table.
pub const SECTIONS: &[(&str, &[&Key])] = &[
    ("vehicle", vehicle::KEYS),
    ("ingest", ingest::KEYS),
    ("filters", filters::KEYS),
    ("estimate", estimate::KEYS),
    ("contact", contact::KEYS),
    ("train", train::KEYS),
];

/// A validated pipeline.
#[derive(Debug, Clone, PartialEq)]
pub struct Pipeline {
    /// Where it was read from (a path, or [`DEFAULT_PIPELINE_NAME`]).
    pub source: String,
    /// The exact text it was parsed from (for provenance hashes).
    pub text: String,
    pub vehicle: Vehicle,
    pub ingest: IngestConfig,
    pub filters: FilterConfig,
    pub estimate: EstimateConfig,
    pub contact: ContactConfig,
    pub train: TrainConfig,
    /// A calibration fitted from data (`estimate.calibration` = "campaign" or "dry-run"),
    /// set by the campaign before its runs are estimated, never by the file; every estimate
    /// made with this pipeline applies it, and a run's reuse key includes it.
    pub calibrated: Option<calibrated::Calibrated>,
}

impl Pipeline {
    /// The embedded default pipeline.
    pub fn default_uic_z1() -> Pipeline {
        Self::from_toml(DEFAULT_PIPELINE_TOML, DEFAULT_PIPELINE_NAME)
            .expect("the embedded default pipeline passes its own checks (tested)")
    }

    /// Loads `path`, or the embedded default when `None`.
    pub fn load(path: Option<&Path>) -> Result<Pipeline, ConfigError> {
        match path {
            None => Ok(Self::default_uic_z1()),
            Some(p) => {
                let file = p.display().to_string();
                let text = crate::input::read_text_limited(
                    p,
                    crate::input::MAX_CONFIG_BYTES,
                    "pipeline file",
                )
                .map_err(|source| ConfigError::Read {
                    file: file.clone(),
                    source,
                })?;
                Self::from_toml(&text, &file)
            }
        }
    }

    /// Parses and checks pipeline TOML; `file` names it in errors.
    pub fn from_toml(text: &str, file: &str) -> Result<Pipeline, ConfigError> {
        let raw: raw::Pipeline = toml::from_str(text).map_err(|e| ConfigError::Syntax {
            file: file.to_string(),
            message: e.to_string().trim_end().to_string(),
        })?;
        let c = Checker { file };
        let vehicle = c.vehicle(raw.vehicle)?;
        let ingest = c.ingest(raw.ingest)?;
        let filters = c.filters(raw.filters, ingest.sample_rate_hz)?;
        let estimate = c.estimate(raw.estimate)?;
        let contact = c.contact(raw.contact)?;
        let train = c.train(raw.train)?;
        Ok(Pipeline {
            source: file.to_string(),
            text: text.to_string(),
            vehicle,
            ingest,
            filters,
            estimate,
            contact,
            train,
            calibrated: None,
        })
    }
}

/// Checks a raw `[vehicle]` table (shared by pipeline and scene files); `file` names it in
/// errors.
pub fn check_vehicle(v: raw::Vehicle, file: &str) -> Result<Vehicle, ConfigError> {
    Checker { file }.vehicle(Some(v))
}

/// The root of the source tree this library was built from, where `fixtures/` and
/// `pipelines/` live (the bundled archive, the study's plans and scenes).
pub(crate) fn source_tree() -> &'static Path {
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR"));
    manifest.ancestors().nth(2).unwrap_or(manifest)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::format::Signal;

    fn with_vehicle(extra: &str) -> String {
        let base = DEFAULT_PIPELINE_TOML;
        format!("{base}\n{extra}")
    }

    #[test]
    fn every_input_set_parses_with_its_default_support_grid() {
        for set in crate::model::InputSet::ALL {
            let names: Vec<String> = set.names().iter().map(|n| format!("\"{}\"", n.0)).collect();
            let text = DEFAULT_PIPELINE_TOML.replace(
                "inputs = [\"dv_mps\", \"ddv_mps2\"]",
                &format!("inputs = [{}]", names.join(", ")),
            );
            let p = Pipeline::from_toml(&text, "p.toml").unwrap();
            assert_eq!(p.train.inputs, set);
            assert_eq!(p.train.support_cells, default_support_cells(set.count()));
        }
    }

    #[test]
    fn embedded_default_passes_its_checks_with_contract_names() {
        let p = Pipeline::default_uic_z1();
        assert_eq!(p.vehicle.wheel_radius_m, 0.445);
        assert_eq!(p.vehicle.brake_torque_nm_per_bar, [1600.0; 4]);
        assert_eq!(p.ingest.sample_rate_hz, 417.0);
        assert!((p.ingest.max_gap_s - 0.05).abs() < 1e-15);
        for s in Signal::ALL {
            assert_eq!(p.ingest.csv_column(s).column, s.key());
            assert_eq!(p.ingest.mcap_field(s).topic, s.mcap_topic());
            assert_eq!(p.ingest.mcap_field(s).field, s.mcap_field());
            assert_eq!(p.ingest.csv_column(s).unit, s.quantity().canonical());
        }
    }

    #[test]
    fn a_minimal_file_gets_contract_defaults_for_ingest() {
        let vehicle_only: String = DEFAULT_PIPELINE_TOML
            .split("[ingest]")
            .next()
            .unwrap()
            .to_string();
        let p = Pipeline::from_toml(&vehicle_only, "v.toml").unwrap();
        assert_eq!(p.ingest, Pipeline::default_uic_z1().ingest);
    }

    #[test]
    fn out_of_range_value_names_key_value_range_and_default() {
        let text = DEFAULT_PIPELINE_TOML.replace("max_gap_ms = 50.0", "max_gap_ms = -5.0");
        let e = Pipeline::from_toml(&text, "p.toml")
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "p.toml: ingest.max_gap_ms = -5: must be > 2.3981 ms and <= 10000 ms (default 50 ms); the lower bound is one sample period"
        );
    }

    #[allow(clippy::too_many_lines)] // a test or benchmark: one scenario end to end
    #[test]
    fn bad_filter_estimate_contact_and_train_keys_name_the_key_and_the_rule() {
        let err = |from: &str, to: &str| {
            assert!(DEFAULT_PIPELINE_TOML.contains(from), "{from}");
            Pipeline::from_toml(&DEFAULT_PIPELINE_TOML.replace(from, to), "p.toml")
                .unwrap_err()
                .to_string()
        };
        let cases = [
            (
                "mode = \"zero_phase\"",
                "mode = \"acausal\"",
                "p.toml: filters.mode = \"acausal\": must be one of \"zero_phase\", \"causal\"",
            ),
            (
                "despike_half_window_s = 0.025",
                "despike_half_window_s = 0.001",
                "filters.despike_half_window_s = 0.001: must span at least one sample",
            ),
            (
                "phase = \"braking\"",
                "phase = \"coasting\"",
                "estimate.phase = \"coasting\": must be one of \"braking\", \"traction\"",
            ),
            (
                "min_speed_mps = 1.0",
                "min_speed_mps = 0.0",
                "estimate.min_speed_mps = 0: must be > 0 m/s",
            ),
            (
                "poisson = 0.3",
                "poisson = 0.5",
                "contact.poisson = 0.5: must be >= 0 and <= 0.49",
            ),
            (
                "split = \"axles\"",
                "split = \"random\"",
                "train.split = \"random\": must be one of \"axles\", \"runs\", \"blocks\"",
            ),
            (
                "val_axles = [3]",
                "val_axles = [2]",
                "train.val_axles = [2]: must not repeat a training axle",
            ),
            (
                "train_axles = [2]",
                "train_axles = [5]",
                "train.train_axles = [5]: must list axles 1..4",
            ),
            (
                "inputs = [\"dv_mps\", \"ddv_mps2\"]",
                "inputs = [\"v_mps\"]",
                "train.inputs = [\"v_mps\"]: must be [\"dv_mps\", \"ddv_mps2\"]",
            ),
            (
                "hidden = 10",
                "hidden = 2.5",
                "train.hidden = 2.5: must be a whole number",
            ),
            ("starts = 1 ", "starts = 0 ", "train.starts = 0: must be"),
            (
                "hidden = 10",
                "hidden = 10\nmax_pooled_samples = 100",
                "train.max_pooled_samples = 100: must be",
            ),
            (
                "hidden = 10",
                "hidden = 10\nmax_pooled_samples = 20000.5",
                "train.max_pooled_samples = 20000.5: must be a whole number",
            ),
            (
                "hidden = 10",
                "layers = [32, 32, 32]",
                "train.layers = [32, 32, 32]: Levenberg–Marquardt trains one or two hidden layers: set train.optimizer = \"adam\"",
            ),
            (
                "hidden = 10",
                "layers = [32, 0]\noptimizer = \"adam\"",
                "train.layers = [32.0, 0.0]: must list 1 to 8 hidden-layer widths",
            ),
            (
                "hidden = 10",
                "layers = [2, 2, 2, 2, 2, 2, 2, 2, 2]\noptimizer = \"adam\"",
                "must list 1 to 8 hidden-layer widths",
            ),
            (
                "hidden = 10",
                "hidden = 10\nlayers = [8]",
                "train.hidden = 10: give either train.hidden or train.layers",
            ),
            (
                "hidden = 10",
                "optimizer = \"sgd\"",
                "train.optimizer = \"sgd\": must be one of \"lm\", \"adam\", \"adamw\"",
            ),
            (
                "hidden = 10",
                "learning_rate = 0.01",
                "train.learning_rate = (given): is a setting of train.optimizer = \"adam\" or \"adamw\"",
            ),
            (
                "hidden = 10",
                "optimizer = \"adam\"\nlearning_rate = 0.0",
                "train.learning_rate = 0",
            ),
            (
                "regularisation = \"none\"",
                "regularisation = \"bayesian\"\noptimizer = \"adamw\"",
                "train.regularisation = \"bayesian\": Bayesian regularisation is MATLAB trainbr",
            ),
            (
                "ensemble = 1 ",
                "ensemble = 2\noptimizer = \"adam\"\n#",
                "train.ensemble = 2: an ensemble averages Levenberg–Marquardt networks",
            ),
            (
                "ensemble = 1 ",
                "ensemble = 5 ",
                "train.ensemble = 5: must be at most train.starts (1)",
            ),
            (
                "regularisation = \"none\"",
                "regularisation = \"ridge\"",
                "train.regularisation = \"ridge\": must be one of",
            ),
            (
                "hidden = 10",
                "hidden = 10\nsupport_cells = [24, 24, 8]",
                "train.support_cells = [24.0, 24.0, 8.0]: must give 2 whole counts (one per input)",
            ),
            (
                "inputs = [\"dv_mps\", \"ddv_mps2\"]",
                "inputs = [\"dv_mps\", \"ddv_mps2\", \"v_mps\"]\nsupport_cells = [1024, 1024, 2]",
                "at most 1048576 cells in all",
            ),
            (
                "hidden = 10",
                "hidden = 10\nsupport_cells = [1000, 2000]",
                "each 2..=1024",
            ),
            (
                "inputs = [\"dv_mps\", \"ddv_mps2\"]",
                "inputs = [\"dv_mps\", \"ddv_mps2\", \"ambient_temperature_c\"]",
                "or [\"dv_mps\", \"ddv_mps2\", \"v_mps\", \"ambient_temperature_c\"]",
            ),
            (
                "inputs = [\"dv_mps\", \"ddv_mps2\"]",
                "inputs = [\"dv_mps\", \"ddv_mps2\", \"v_mps\", \"ambient_temperature_c\"]\nsupport_cells = [16, 16, 8]",
                "must give 4 whole counts (one per input)",
            ),
            (
                "mu_dec = 0.1",
                "mu_dec = 1.5",
                "train.mu_dec = 1.5: must be >= 1e-6 and <= 0.999 (default 0.1)",
            ),
            (
                "# condition = \"soap\"",
                "condition = \"\"",
                "train.condition = \"\": a rail condition as in the runs' metadata",
            ),
        ];
        for (from, to, want) in cases {
            let e = err(from, to);
            assert!(e.contains(want), "{to}: {e}");
        }
    }

    #[test]
    fn implausible_vehicle_is_rejected() {
        let text = DEFAULT_PIPELINE_TOML.replace("wheel_radius_m = 0.445", "wheel_radius_m = 4.45");
        let e = Pipeline::from_toml(&text, "p.toml")
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "p.toml: vehicle.wheel_radius_m = 4.45: must be >= 0.2 m and <= 0.7 m"
        );
        let text = DEFAULT_PIPELINE_TOML
            .replace("bogie_wheelbase_m = 2.56", "bogie_wheelbase_m = 4.0")
            .replace(
                "bogie_pivot_distance_m = 19.0",
                "bogie_pivot_distance_m = 3.0",
            );
        let e = Pipeline::from_toml(&text, "p.toml")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("vehicle.bogie_wheelbase_m = 4: must be shorter than"),
            "{e}"
        );
        let text = DEFAULT_PIPELINE_TOML.replace(
            "[1600.0, 1600.0, 1600.0, 1600.0]",
            "[1600.0, 1600.0, -1.0, 1600.0]",
        );
        let e = Pipeline::from_toml(&text, "p.toml")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("vehicle.brake_torque_nm_per_bar[2] (axle 3) = -1"),
            "{e}"
        );
    }

    #[test]
    fn missing_vehicle_key_quotes_the_uic_z1_value() {
        let text = DEFAULT_PIPELINE_TOML.replace("axle_inertia_kgm2 = 120.0", "");
        let e = Pipeline::from_toml(&text, "p.toml")
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "p.toml: vehicle.axle_inertia_kgm2 is missing: give it in kg·m², must be > 1 kg·m² and <= 2000 kg·m² (UIC-Z1: 120)"
        );
    }

    #[test]
    fn unknown_unit_lists_the_accepted_ones() {
        let text = with_vehicle("");
        let text = text.replace(
            r#"v_radar = { column = "v_radar", unit = "m/s" }"#,
            r#"v_radar = { column = "speed", unit = "mph" }"#,
        );
        let e = Pipeline::from_toml(&text, "p.toml")
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            r#"p.toml: ingest.csv.v_radar.unit = "mph": unknown speed unit; use one of "m/s", "km/h" (default "m/s")"#
        );
    }

    #[test]
    fn unknown_keys_and_bad_actions_are_rejected() {
        let text =
            DEFAULT_PIPELINE_TOML.replace("max_gap_ms = 50.0", "max_gap_ms = 50.0\nmax_gapp = 3");
        let e = Pipeline::from_toml(&text, "p.toml")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("p.toml: not a valid pipeline file:") && e.contains("max_gapp"),
            "{e}"
        );
        let text = DEFAULT_PIPELINE_TOML.replace(r#"action = "warn""#, r#"action = "ignore""#);
        let e = Pipeline::from_toml(&text, "p.toml")
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            r#"p.toml: ingest.plausibility.action = "ignore": must be one of "warn", "error" (default "warn")"#
        );
    }

    #[test]
    fn misspelled_signal_in_a_mapping_is_named() {
        let text = DEFAULT_PIPELINE_TOML.replace("omega4 = { column", "omgea4 = { column");
        let e = Pipeline::from_toml(&text, "p.toml")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("p.toml: ingest.csv.omgea4 = { … }: unknown signal; the signals are time, v_radar, omega1"), "{e}");
    }

    #[test]
    fn missing_file_error_names_the_file() {
        let e = Pipeline::load(Some(Path::new("/nonexistent/p.toml")))
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("/nonexistent/p.toml: cannot read the pipeline file"),
            "{e}"
        );
    }
}
