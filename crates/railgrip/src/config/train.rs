//! `[train]`: the network, its data and MATLAB trainlm's settings
//! (../shared/design/reference-values.md, tag trainlm), the creep region and the k(T) fits.

use super::rule::{closed, int, open_lo, Checker, Default, Key, Range};
use super::ConfigError;
use crate::format::AXLES;
use crate::model::InputSet;

pub mod raw {
    use serde::Deserialize;

    #[derive(Debug, Default, Deserialize)]
    #[serde(deny_unknown_fields)]
    pub struct Train {
        pub hidden: Option<f64>,
        pub layers: Option<Vec<f64>>,
        pub optimizer: Option<String>,
        pub learning_rate: Option<f64>,
        pub weight_decay: Option<f64>,
        pub batch: Option<f64>,
        pub inputs: Option<Vec<String>>,
        pub split: Option<String>,
        pub train_axles: Option<Vec<u8>>,
        pub val_axles: Option<Vec<u8>>,
        pub val_every: Option<f64>,
        pub block_s: Option<f64>,
        pub decimate: Option<f64>,
        pub seed: Option<u64>,
        pub starts: Option<f64>,
        pub ensemble: Option<f64>,
        pub regularisation: Option<String>,
        pub epochs: Option<f64>,
        pub goal: Option<f64>,
        pub max_fail: Option<f64>,
        pub min_grad: Option<f64>,
        pub mu: Option<f64>,
        pub mu_dec: Option<f64>,
        pub mu_inc: Option<f64>,
        pub mu_max: Option<f64>,
        pub creep_blend_mps: Option<f64>,
        pub temperature_degree: Option<f64>,
        pub condition: Option<String>,
        pub support_cells: Option<Vec<f64>>,
        pub support_min_samples: Option<f64>,
        pub audit_mu_max: Option<f64>,
        pub leave_one_run_out: Option<bool>,
        pub polach_intervals: Option<bool>,
        pub model: Option<String>,
        pub folds: Option<f64>,
        pub max_pooled_samples: Option<f64>,
    }
}

/// Which model a campaign exports as its model (`train.model`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ModelChoice {
    /// Every candidate scored by held-out runs, the best chosen (docs/training.md#model-choice).
    Auto,
    /// The network of `[train]` (seed 002).
    Mlp,
    /// The grey-box network over the campaign's Polach law.
    Residual,
    /// Polach's law with the temperature and speed laws BIC chose.
    Polach,
}

impl ModelChoice {
    pub fn name(self) -> &'static str {
        match self {
            ModelChoice::Auto => "auto",
            ModelChoice::Mlp => "mlp",
            ModelChoice::Residual => "residual",
            ModelChoice::Polach => "polach",
        }
    }
}

/// How training and validation samples are chosen.
#[derive(Debug, Clone, PartialEq)]
pub enum SplitConfig {
    /// By axle, pooled over the runs (seed 002: train on axle 2, validate on axle 3).
    Axles { train: Vec<u8>, val: Vec<u8> },
    /// Every `every`-th run validates.
    Runs { every: usize },
    /// Every `every`-th block of `block_s` seconds validates.
    Blocks { block_s: f64, every: usize },
}

/// Which first-order optimiser trains through burn (`identify::adam`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Optimizer {
    /// Adam with an L2 penalty folded into the gradient when `weight_decay` > 0.
    Adam,
    /// AdamW: the weight decay decoupled from the gradient.
    AdamW,
}

impl Optimizer {
    pub fn name(self) -> &'static str {
        match self {
            Optimizer::Adam => "adam",
            Optimizer::AdamW => "adamw",
        }
    }
}

/// Which trainer fits the network.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Trainer {
    /// Levenberg–Marquardt (MATLAB trainlm/trainbr): one or two hidden layers.
    Lm,
    /// Mini-batch Adam or AdamW through burn: any depth.
    Burn(Optimizer),
}

/// Training settings.
#[derive(Debug, Clone, PartialEq)]
pub struct TrainConfig {
    /// Neurons of the first hidden layer (`layers[0]`).
    pub hidden: usize,
    /// Neurons per hidden layer, in order (`[hidden]` unless `train.layers` is given).
    pub layers: Vec<usize>,
    pub trainer: Trainer,
    /// Adam/AdamW: step size, decay (AdamW decoupled, Adam L2) and mini-batch size.
    pub learning_rate: f64,
    pub weight_decay: f64,
    pub batch: usize,
    /// The network's inputs (speed third, ambient temperature fourth).
    pub inputs: InputSet,
    pub split: SplitConfig,
    /// Keep every n-th valid sample of a run and axle.
    pub decimate: usize,
    pub seed: u64,
    /// Nguyen–Widrow starts (seeds seed, seed + 1, …) trained in parallel; the one with the
    /// lowest validation error is kept.
    pub starts: usize,
    /// The best `ensemble` starts (by validation error) averaged into one network; 1: the best
    /// start alone.
    pub ensemble: usize,
    /// Bayesian regularisation (MATLAB trainbr) instead of trainlm.
    pub bayesian: bool,
    pub epochs: u64,
    pub goal: f64,
    pub max_fail: u32,
    pub min_grad: f64,
    pub mu: f64,
    pub mu_dec: f64,
    pub mu_inc: f64,
    pub mu_max: f64,
    /// Width of the small-slip region where the model blends from the linear creep law into
    /// the network, m/s.
    pub creep_blend_mps: f64,
    /// Polynomial degree of the k_A(T), k_S(T) fits.
    pub temperature_degree: usize,
    /// Rail condition (run metadata `condition`) whose runs train the models; None: the
    /// campaign's most common condition.
    pub condition: Option<String>,
    /// Cells per input of the model file's data-support grid (one per input).
    pub support_cells: Vec<usize>,
    /// Training and validation samples a support cell needs.
    pub support_min_samples: u64,
    /// The plausibility audit's ceiling: 0 ≤ μ ≤ this on every supported cell.
    pub audit_mu_max: f64,
    /// Leave-one-run-out scores for the report (one more training per run; per fold of runs
    /// beyond `folds` runs).
    pub leave_one_run_out: bool,
    /// Profile-likelihood intervals of the pooled and per-temperature Polach fits.
    pub polach_intervals: bool,
    /// The campaign's model: chosen by held-out runs, or named.
    pub model: ModelChoice,
    /// Held-out folds of runs for the model choice and leave-one-run-out: one run out at a
    /// time up to this many runs, this many folds of runs beyond.
    pub folds: usize,
    /// Pooled valid samples (all runs and axles of the training condition) above which every
    /// run and axle is thinned to every m-th sample before training, with a note.
    pub max_pooled_samples: usize,
}

/// MATLAB trainbr's initial μ (reference-values.md, tag trainbr).
pub const TRAINBR_MU: f64 = 0.005;
/// `train.support_min_samples` when the file leaves it out.
pub const DEFAULT_SUPPORT_MIN_SAMPLES: u64 = 10;
/// `train.audit_mu_max` when the file leaves it out.
pub const DEFAULT_AUDIT_MU_MAX: f64 = 0.6;

/// Default support grid: 24 × 24 cells for two inputs, 16 × 16 × 8 for three,
/// 16 × 16 × 8 × 4 for four (runs at few ambient temperatures: each of four temperature
/// cells holds whole runs).
pub fn default_support_cells(inputs: usize) -> Vec<usize> {
    match inputs {
        4 => vec![16, 16, 8, 4],
        3 => vec![16, 16, 8],
        _ => vec![24, 24],
    }
}

const fn text(
    name: &'static str,
    range: &'static str,
    default: &'static str,
    meaning: &'static str,
) -> Key {
    Key {
        name,
        unit: "",
        range: Range::Text(range),
        default: Default::Text(default),
        meaning,
    }
}

const HIDDEN: Key = Key::num(
    "train.hidden",
    "",
    int(1.0, 200.0),
    10.0,
    "hidden tanh neurons [pub]",
);
const LAYERS: Key = text(
    "train.layers",
    "1 to 8 widths, each 1..256; more than 2 need an Adam optimiser",
    "`[hidden]`",
    "neurons per hidden tanh layer, e.g. `[32, 32]` (replaces `hidden`; model files of more than one layer are format version 3)",
);
const OPTIMIZER: Key = Key {
    name: "train.optimizer",
    unit: "",
    range: Range::Choice(&["lm", "adam", "adamw"]),
    default: Default::Text("\"lm\""),
    meaning: "`lm`: Levenberg–Marquardt (trainlm/trainbr, one or two hidden layers); `adam`/`adamw`: mini-batch Adam/AdamW through burn, any depth (`epochs` and `max_fail` are its epochs and patience; docs/training.md#training-deeper-networks)",
};
const LEARNING_RATE: Key = Key::num(
    "train.learning_rate",
    "",
    open_lo(0.0, 0.5),
    1e-3,
    "Adam/AdamW: step size α on the normalised data",
);
const WEIGHT_DECAY: Key = Key::num(
    "train.weight_decay",
    "",
    closed(0.0, 0.5),
    0.0,
    "Adam: L2 penalty; AdamW: decoupled decay λ",
);
const BATCH: Key = Key::num(
    "train.batch",
    "",
    int(1.0, 1e6),
    256.0,
    "Adam/AdamW: samples per mini-batch",
);
const INPUTS: Key = text(
    "train.inputs",
    "`[\"dv_mps\", \"ddv_mps2\"]`, with `\"v_mps\"`, or with `\"v_mps\", \"ambient_temperature_c\"`",
    "`[\"dv_mps\", \"ddv_mps2\"]`",
    "network inputs (seed 002; speed as a third; the runs' ambient temperature, from their metadata, as a fourth) [pub]",
);
const SPLIT: Key = Key {
    name: "train.split",
    unit: "",
    range: Range::Choice(&["axles", "runs", "blocks"]),
    default: Default::Text("\"axles\""),
    meaning: "how validation samples are chosen",
};
const TRAIN_AXLES: Key = text(
    "train.train_axles",
    "axles 1..4",
    "[2]",
    "`\"axles\"` split: training axles (seed 002) [pub]",
);
const VAL_AXLES: Key = text(
    "train.val_axles",
    "axles 1..4, none of train_axles",
    "[3]",
    "`\"axles\"` split: validation axles [pub]",
);
const VAL_EVERY: Key = Key::num(
    "train.val_every",
    "",
    int(2.0, 1000.0),
    4.0,
    "`\"runs\"`/`\"blocks\"`: every n-th run or block validates",
);
const BLOCK: Key = Key::num(
    "train.block_s",
    "s",
    open_lo(0.0, 3600.0),
    5.0,
    "`\"blocks\"`: block length",
);
const DECIMATE: Key = Key::num(
    "train.decimate",
    "",
    int(1.0, 1000.0),
    4.0,
    "keep every n-th valid sample per run and axle",
);
const SEED: Key = text(
    "train.seed",
    "0..2⁶⁴−1",
    "1",
    "Nguyen–Widrow initialisation",
);
const STARTS: Key = Key::num(
    "train.starts",
    "",
    int(1.0, 256.0),
    1.0,
    "Nguyen–Widrow starts (seeds seed, seed + 1, …) trained in parallel, the lowest validation error kept",
);
const ENSEMBLE: Key = Key::num(
    "train.ensemble",
    "",
    int(1.0, 256.0),
    1.0,
    "the best this many starts averaged into one network (the spread kept as an uncertainty band); at most `starts`",
);
const REGULARISATION: Key = Key {
    name: "train.regularisation",
    unit: "",
    range: Range::Choice(&["none", "bayesian"]),
    default: Default::Text("\"none\""),
    meaning: "`bayesian`: MATLAB trainbr (γ per epoch; μ 0.005 and validation stop off unless given) [pub]",
};
const EPOCHS: Key = Key::num(
    "train.epochs",
    "",
    int(1.0, 1e6),
    1000.0,
    "trainlm: most epochs [pub]",
);
const GOAL: Key = Key::num(
    "train.goal",
    "",
    closed(0.0, 1.0),
    0.0,
    "trainlm: stop at this training MSE [pub]",
);
const MAX_FAIL: Key = Key::num(
    "train.max_fail",
    "",
    int(1.0, 1e6),
    6.0,
    "trainlm: validation checks [pub]",
);
const MIN_GRAD: Key = Key::num(
    "train.min_grad",
    "",
    closed(0.0, 1.0),
    1e-7,
    "trainlm: stop below this gradient norm [pub]",
);
const MU: Key = Key::num(
    "train.mu",
    "",
    closed(1e-12, 1e6),
    1e-3,
    "trainlm: initial damping μ [pub]",
);
const MU_DEC: Key = Key::num(
    "train.mu_dec",
    "",
    closed(1e-6, 0.999),
    0.1,
    "trainlm: μ factor after a good step [pub]",
);
const MU_INC: Key = Key::num(
    "train.mu_inc",
    "",
    closed(1.001, 1e6),
    10.0,
    "trainlm: μ factor after a bad step [pub]",
);
const MU_MAX: Key = Key::num(
    "train.mu_max",
    "",
    closed(1.0, 1e20),
    1e10,
    "trainlm: stop when μ exceeds this [pub]",
);
const CREEP_BLEND: Key = Key::num(
    "train.creep_blend_mps",
    "m/s",
    closed(1e-3, 5.0),
    0.2,
    "Δv_b: below it the model blends from the linear creep law into the network",
);
const DEGREE: Key = Key::num(
    "train.temperature_degree",
    "",
    int(0.0, 5.0),
    2.0,
    "highest degree of the temperature law μ0(T), k_A(T), k_S(T), chosen by BIC (capped at temperatures − 1)",
);
const SUPPORT_CELLS: Key = text(
    "train.support_cells",
    "one count per input, each 2..1024, at most 2²⁰ cells",
    "`[24, 24]`; `[16, 16, 8]` with speed; `[16, 16, 8, 4]` with temperature",
    "the model file's data-support grid over the normalised inputs (docs/model-files.md#data-support)",
);
const SUPPORT_MIN: Key = Key::num(
    "train.support_min_samples",
    "",
    int(1.0, 1e9),
    DEFAULT_SUPPORT_MIN_SAMPLES as f64,
    "training and validation samples a support cell needs",
);
const AUDIT_MU_MAX: Key = Key::num(
    "train.audit_mu_max",
    "",
    open_lo(0.0, 2.0),
    DEFAULT_AUDIT_MU_MAX,
    "plausibility audit: 0 ≤ μ ≤ this on every supported cell",
);
const LEAVE_ONE_OUT: Key = text(
    "train.leave_one_run_out",
    "`true`, `false`",
    "`true`",
    "score networks trained without each run on that run (report; one single-start training per run — per fold of runs beyond `train.folds` runs — or with `train.model = \"auto\"` the model choice's folds of the network)",
);
const POLACH_INTERVALS: Key = text(
    "train.polach_intervals",
    "`true`, `false`",
    "`true`",
    "profile-likelihood 95 % intervals of the pooled and per-temperature Polach fits (about 30 LM refits per fit; docs/training.md#intervals)",
);
const MODEL: Key = Key {
    name: "train.model",
    unit: "",
    range: Range::Choice(&["auto", "mlp", "residual", "polach"]),
    default: Default::Text("\"auto\""),
    meaning: "the campaign's model: `auto` scores every candidate (2/3/4-input network, residual network, Polach with its laws) on held-out runs and exports the best; `mlp` the network of `[train]` (seed 002), `residual` the grey-box network over the Polach law, `polach` the law alone (docs/training.md#model-choice)",
};
const FOLDS: Key = Key::num(
    "train.folds",
    "",
    int(2.0, 1000.0),
    8.0,
    "held-out runs of the model choice (`auto`) and of leave-one-run-out: one run out at a time up to this many runs, this many folds of runs beyond (run i in fold i mod K)",
);
const MAX_POOLED: Key = Key::num(
    "train.max_pooled_samples",
    "",
    int(1e4, 1e10),
    20e6,
    "pooled valid samples (runs × axles of the training condition) the training holds: beyond it every run and axle keeps every m-th sample, m the smallest that fits, with a note in the report; while the runs are estimated, tables beyond it wait in their estimates files (memory: docs/benchmarks.md#how-it-grows-with-the-campaign)",
);
const CONDITION: Key = text(
    "train.condition",
    "a run metadata `condition`",
    "(most common)",
    "the rail condition whose runs train the network and the Polach fits",
);

/// The keys of `[train]`, in the order of the documented table.
pub const KEYS: &[&Key] = &[
    &HIDDEN,
    &LAYERS,
    &OPTIMIZER,
    &LEARNING_RATE,
    &WEIGHT_DECAY,
    &BATCH,
    &INPUTS,
    &SPLIT,
    &TRAIN_AXLES,
    &VAL_AXLES,
    &VAL_EVERY,
    &BLOCK,
    &DECIMATE,
    &SEED,
    &STARTS,
    &ENSEMBLE,
    &REGULARISATION,
    &EPOCHS,
    &GOAL,
    &MAX_FAIL,
    &MIN_GRAD,
    &MU,
    &MU_DEC,
    &MU_INC,
    &MU_MAX,
    &CREEP_BLEND,
    &DEGREE,
    &CONDITION,
    &SUPPORT_CELLS,
    &SUPPORT_MIN,
    &AUDIT_MU_MAX,
    &LEAVE_ONE_OUT,
    &POLACH_INTERVALS,
    &MODEL,
    &FOLDS,
    &MAX_POOLED,
];

impl Checker<'_> {
    /// Checks `[train]`. The checks run in the order of the steps below (the first failing
    /// key is the one reported): the inputs and the rail condition, the regularisation and
    /// the optimiser, the hidden layers, which trainer can train them, the starts and the
    /// ensemble, the Adam-only keys, the support grid, then every other key in field order.
    pub(crate) fn train(&self, t: raw::Train) -> Result<TrainConfig, ConfigError> {
        let inputs = self.train_inputs(&t)?;
        let condition = self.train_condition(&t)?;
        let bayesian = self.choice(
            &REGULARISATION,
            t.regularisation.clone(),
            &[("none", false), ("bayesian", true)],
            false,
        )?;
        let trainer = self.choice(
            &OPTIMIZER,
            t.optimizer.clone(),
            &[
                ("lm", Trainer::Lm),
                ("adam", Trainer::Burn(Optimizer::Adam)),
                ("adamw", Trainer::Burn(Optimizer::AdamW)),
            ],
            Trainer::Lm,
        )?;
        let layers = self.train_layers(&t)?;
        self.check_train_trainer(trainer, bayesian, &layers)?;
        let (starts, ensemble) = self.train_starts_and_ensemble(&t, trainer, &layers)?;
        self.check_train_adam_keys(&t, trainer)?;
        let support_cells = self.train_support_cells(&t, inputs.count())?;
        Ok(TrainConfig {
            hidden: layers[0],
            layers,
            trainer,
            learning_rate: self.value(&LEARNING_RATE, t.learning_rate)?,
            weight_decay: self.value(&WEIGHT_DECAY, t.weight_decay)?,
            batch: self.value(&BATCH, t.batch)? as usize,
            inputs,
            split: self.split(&t)?,
            decimate: self.value(&DECIMATE, t.decimate)? as usize,
            seed: t.seed.unwrap_or(1),
            starts,
            ensemble,
            bayesian,
            epochs: self.value(&EPOCHS, t.epochs)? as u64,
            goal: self.value(&GOAL, t.goal)?,
            max_fail: if bayesian && t.max_fail.is_none() {
                0
            } else {
                self.value(&MAX_FAIL, t.max_fail)? as u32
            },
            min_grad: self.value(&MIN_GRAD, t.min_grad)?,
            mu: if bayesian && t.mu.is_none() {
                TRAINBR_MU
            } else {
                self.value(&MU, t.mu)?
            },
            mu_dec: self.value(&MU_DEC, t.mu_dec)?,
            mu_inc: self.value(&MU_INC, t.mu_inc)?,
            mu_max: self.value(&MU_MAX, t.mu_max)?,
            creep_blend_mps: self.value(&CREEP_BLEND, t.creep_blend_mps)?,
            temperature_degree: self.value(&DEGREE, t.temperature_degree)? as usize,
            condition,
            support_cells,
            support_min_samples: self.value(&SUPPORT_MIN, t.support_min_samples)? as u64,
            audit_mu_max: self.value(&AUDIT_MU_MAX, t.audit_mu_max)?,
            leave_one_run_out: t.leave_one_run_out.unwrap_or(true),
            polach_intervals: t.polach_intervals.unwrap_or(true),
            model: self.choice(
                &MODEL,
                t.model.clone(),
                &[
                    ("auto", ModelChoice::Auto),
                    ("mlp", ModelChoice::Mlp),
                    ("residual", ModelChoice::Residual),
                    ("polach", ModelChoice::Polach),
                ],
                ModelChoice::Auto,
            )?,
            folds: self.value(&FOLDS, t.folds)? as usize,
            max_pooled_samples: self.value(&MAX_POOLED, t.max_pooled_samples)? as usize,
        })
    }

    /// `train.inputs`: one of the [`InputSet`]s by its names (Δv and dΔv/dt when left out).
    fn train_inputs(&self, t: &raw::Train) -> Result<InputSet, ConfigError> {
        Ok(match t.inputs.as_deref() {
            None => InputSet::DvDdv,
            Some(names) => InputSet::from_names(names).ok_or_else(|| {
                self.invalid(
                    INPUTS.name,
                    format!("{names:?}"),
                    "must be [\"dv_mps\", \"ddv_mps2\"] (seed 002), [\"dv_mps\", \"ddv_mps2\", \"v_mps\"] or [\"dv_mps\", \"ddv_mps2\", \"v_mps\", \"ambient_temperature_c\"]",
                )
            })?,
        })
    }

    /// `train.condition`: a rail condition that is not blank (`None`: the most common one).
    fn train_condition(&self, t: &raw::Train) -> Result<Option<String>, ConfigError> {
        Ok(match t.condition.clone() {
            Some(c) if c.trim().is_empty() => {
                return Err(self.invalid(
                    CONDITION.name,
                    "\"\"",
                    "a rail condition as in the runs' metadata, e.g. \"soap\"; leave the key out for the most common one",
                ))
            }
            c => c,
        })
    }

    /// The hidden layers' widths: `train.hidden` alone, or `train.layers` (1 to
    /// `MAX_HIDDEN_LAYERS` whole widths of 1 to `MAX_HIDDEN`), never both.
    fn train_layers(&self, t: &raw::Train) -> Result<Vec<usize>, ConfigError> {
        let hidden = self.value(&HIDDEN, t.hidden)? as usize;
        Ok(match &t.layers {
            None => vec![hidden],
            Some(v) => {
                let ok = (1..=crate::model::MAX_HIDDEN_LAYERS).contains(&v.len())
                    && v.iter().all(|n| {
                        n.fract() == 0.0 && (1.0..=crate::model::MAX_HIDDEN as f64).contains(n)
                    });
                if !ok {
                    return Err(self.invalid(
                        LAYERS.name,
                        format!("{v:?}"),
                        format!(
                            "must list 1 to {} hidden-layer widths, each a whole number 1..={}, e.g. [32, 32]",
                            crate::model::MAX_HIDDEN_LAYERS,
                            crate::model::MAX_HIDDEN
                        ),
                    ));
                }
                if t.hidden.is_some() {
                    return Err(self.invalid(
                        HIDDEN.name,
                        hidden.to_string(),
                        "give either train.hidden or train.layers (whose first entry is the first layer's width), not both",
                    ));
                }
                v.iter().map(|n| *n as usize).collect()
            }
        })
    }

    /// Levenberg–Marquardt trains one or two hidden layers; Bayesian regularisation is an LM
    /// variant.
    fn check_train_trainer(
        &self,
        trainer: Trainer,
        bayesian: bool,
        layers: &[usize],
    ) -> Result<(), ConfigError> {
        if trainer == Trainer::Lm && layers.len() > 2 {
            return Err(self.invalid(
                LAYERS.name,
                format!("{layers:?}"),
                "Levenberg–Marquardt trains one or two hidden layers: set train.optimizer = \"adam\" or \"adamw\" for deeper networks",
            ));
        }
        if trainer != Trainer::Lm && bayesian {
            return Err(self.invalid(
                REGULARISATION.name,
                "\"bayesian\"",
                "Bayesian regularisation is MATLAB trainbr, a Levenberg–Marquardt variant: use train.optimizer = \"lm\", or weight_decay with adam/adamw",
            ));
        }
        Ok(())
    }

    /// `train.starts` and `train.ensemble`: an ensemble averages at most `starts`
    /// Levenberg–Marquardt networks of one hidden layer.
    fn train_starts_and_ensemble(
        &self,
        t: &raw::Train,
        trainer: Trainer,
        layers: &[usize],
    ) -> Result<(usize, usize), ConfigError> {
        let starts = self.value(&STARTS, t.starts)? as usize;
        let ensemble = self.value(&ENSEMBLE, t.ensemble)? as usize;
        if ensemble > 1 && trainer != Trainer::Lm {
            return Err(self.invalid(
                ENSEMBLE.name,
                ensemble.to_string(),
                "an ensemble averages Levenberg–Marquardt networks: use train.optimizer = \"lm\", or ensemble = 1",
            ));
        }
        if ensemble > starts {
            return Err(self.invalid(
                ENSEMBLE.name,
                ensemble.to_string(),
                format!("must be at most train.starts ({starts}): raise starts or lower ensemble"),
            ));
        }
        if ensemble > 1 && layers.len() > 1 {
            return Err(self.invalid(
                ENSEMBLE.name,
                ensemble.to_string(),
                "an ensemble averages networks of one hidden layer: use train.hidden, or ensemble = 1",
            ));
        }
        Ok((starts, ensemble))
    }

    /// Levenberg–Marquardt takes none of the Adam/AdamW keys (`learning_rate`,
    /// `weight_decay`, `batch`).
    fn check_train_adam_keys(&self, t: &raw::Train, trainer: Trainer) -> Result<(), ConfigError> {
        if trainer == Trainer::Lm {
            for (key, given) in [
                (&LEARNING_RATE, t.learning_rate.is_some()),
                (&WEIGHT_DECAY, t.weight_decay.is_some()),
                (&BATCH, t.batch.is_some()),
            ] {
                if given {
                    return Err(self.invalid(
                        key.name,
                        "(given)",
                        "is a setting of train.optimizer = \"adam\" or \"adamw\"; Levenberg–Marquardt has none",
                    ));
                }
            }
        }
        Ok(())
    }

    /// `train.support_cells`: one whole count of 2 to `MAX_CELLS_PER_INPUT` per input, at
    /// most `MAX_SUPPORT_CELLS` in all ([`default_support_cells`] when left out).
    fn train_support_cells(
        &self,
        t: &raw::Train,
        n_inputs: usize,
    ) -> Result<Vec<usize>, ConfigError> {
        Ok(match &t.support_cells {
            None => default_support_cells(n_inputs),
            Some(v) => {
                let max = crate::model::MAX_CELLS_PER_INPUT as f64;
                let ok = v.len() == n_inputs
                    && v.iter()
                        .all(|c| c.fract() == 0.0 && (2.0..=max).contains(c));
                let cells: Vec<usize> = v.iter().map(|c| *c as usize).collect();
                let total = cells.iter().try_fold(1usize, |a, &c| a.checked_mul(c));
                if !ok || total.is_none_or(|n| n > crate::model::MAX_SUPPORT_CELLS) {
                    return Err(self.invalid(
                        SUPPORT_CELLS.name,
                        format!("{v:?}"),
                        format!(
                            "must give {n_inputs} whole counts (one per input), each 2..={}, with at most {} cells in all (e.g. {:?})",
                            crate::model::MAX_CELLS_PER_INPUT,
                            crate::model::MAX_SUPPORT_CELLS,
                            default_support_cells(n_inputs)
                        ),
                    ));
                }
                cells
            }
        })
    }

    fn split(&self, t: &raw::Train) -> Result<SplitConfig, ConfigError> {
        let every = self.value(&VAL_EVERY, t.val_every)? as usize;
        let axles = |k: &Key, v: &Option<Vec<u8>>, default: u8| -> Result<Vec<u8>, ConfigError> {
            let v = v.clone().unwrap_or_else(|| vec![default]);
            if v.is_empty() || v.iter().any(|a| !(1..=AXLES as u8).contains(a)) {
                return Err(self.invalid(k.name, format!("{v:?}"), "must list axles 1..4"));
            }
            Ok(v)
        };
        let kind = self.choice(
            &SPLIT,
            t.split.clone(),
            &[("axles", 0), ("runs", 1), ("blocks", 2)],
            0,
        )?;
        Ok(match kind {
            0 => {
                let train = axles(&TRAIN_AXLES, &t.train_axles, 2)?;
                let val = axles(&VAL_AXLES, &t.val_axles, 3)?;
                if let Some(a) = train.iter().find(|a| val.contains(a)) {
                    return Err(self.invalid(
                        VAL_AXLES.name,
                        format!("{val:?}"),
                        format!(
                            "must not repeat a training axle (axle {a} is in {})",
                            TRAIN_AXLES.name
                        ),
                    ));
                }
                SplitConfig::Axles { train, val }
            }
            1 => SplitConfig::Runs { every },
            _ => SplitConfig::Blocks {
                block_s: self.value(&BLOCK, t.block_s)?,
                every,
            },
        })
    }
}
