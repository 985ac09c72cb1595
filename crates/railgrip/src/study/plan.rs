//! The study plan (`pipelines/study.toml`, docs/study.md): a base pipeline and a list
//! of grids. Each `[[grid]]` is the Cartesian product of its keys' values; the plan is the
//! union of its grids, duplicates removed. A grid key is a pipeline key of `[filters]`,
//! `[estimate]`, `[contact]` or `[train]` (written as in a pipeline file, e.g. `train.layers`);
//! its value is a list of values, one cell each (a single non-list value is one cell).
//! `train.model` is the model axis: each cell fits the one model it names ([`FAMILIES`]).
//! Every cell is a complete pipeline checked by the pipeline's own rules, so a plan can vary
//! nothing a pipeline could not say.

use std::collections::BTreeMap;
use std::path::Path;

use super::ladder::{ContactSpec, SimSpec, CONTACT_LAWS};
use super::StudyError;
use crate::config::Pipeline;
use crate::identify::family::{by_name, ModelFamily, Network, FAMILIES};
use crate::sim::Scene;

/// The bundled default plan (`pipelines/study.toml`).
pub const DEFAULT_PLAN_TOML: &str = include_str!("../../../../pipelines/study.toml");
/// How the default plan is named in messages and outputs.
pub const DEFAULT_PLAN_NAME: &str = "<embedded pipelines/study.toml>";

/// Keys of `[study]`, with what they mean (docs/study.md).
pub const STUDY_KEYS: [(&str, &str); 5] = [
    ("pipeline", "base pipeline file, relative to the plan (default: the embedded uic_z1.toml)"),
    ("held_out", "runs scored and never trained on (default: every third run of the trained condition by name; of two runs, the second)"),
    ("max_cells", "a plan with more cells is refused unless --force (default 200)"),
    ("max_minutes", "a plan whose estimated training time is longer is refused unless --force (default 30)"),
    ("eval_points", "held-out inputs each evaluator is timed on (default 4096)"),
];

/// Pipeline sections a grid may vary.
pub const GRID_SECTIONS: [&str; 4] = ["filters", "estimate", "contact", "train"];

/// Pipeline keys whose value is itself a list: a grid gives a list of lists.
const LIST_KEYS: [&str; 5] = [
    "train.layers",
    "train.inputs",
    "train.train_axles",
    "train.val_axles",
    "train.support_cells",
];

/// One cell of the plan.
#[derive(Debug, Clone)]
pub struct CellSpec {
    /// The grid's `label` (or `grid N`).
    pub group: String,
    /// What the cell identifies (one of [`FAMILIES`]).
    pub family: &'static dyn ModelFamily,
    /// The pipeline keys this cell sets, in key order, as TOML text (`train.layers = [10]`).
    pub settings: Vec<(String, String)>,
    /// The complete pipeline of the cell.
    pub pipeline: Pipeline,
    /// The pipeline with the cell's non-`[train]` keys only: what the runs are estimated with
    /// (cells that differ in training only share their estimates).
    pub conditioning: Pipeline,
}

impl CellSpec {
    /// A short name: the group and the keys it sets (`train.` left off).
    pub fn name(&self) -> String {
        let mut s = format!("{} · {}", self.group, self.family.name());
        for (k, v) in &self.settings {
            let k = k.strip_prefix("train.").unwrap_or(k);
            s.push_str(&format!(" · {k}={v}"));
        }
        s
    }
}

/// A checked plan.
#[derive(Debug, Clone)]
pub struct Plan {
    /// Where it was read from.
    pub source: String,
    pub text: String,
    /// The base pipeline's name.
    pub base: String,
    pub held_out: Option<Vec<String>>,
    pub max_cells: usize,
    pub max_minutes: f64,
    pub eval_points: usize,
    pub cells: Vec<CellSpec>,
    /// The base pipeline (the contact rows' patch).
    pub base_pipeline: Pipeline,
    /// `[[simulator]]` and `[[contact]]` rows ([`super::ladder`]).
    pub simulator: Vec<SimSpec>,
    pub contact: Vec<ContactSpec>,
}

fn err(file: &str, what: impl Into<String>, hint: impl Into<String>) -> StudyError {
    StudyError::Plan {
        file: file.to_string(),
        what: what.into(),
        hint: hint.into(),
    }
}

impl Plan {
    /// Reads `path` (or the bundled plan); `pipeline` replaces the plan's base pipeline.
    pub fn load(path: Option<&Path>, pipeline: Option<&Path>) -> Result<Plan, StudyError> {
        let (text, source, dir) = match path {
            None => (
                DEFAULT_PLAN_TOML.to_string(),
                DEFAULT_PLAN_NAME.to_string(),
                None,
            ),
            Some(p) => {
                let text =
                    crate::input::read_text_limited(p, crate::input::MAX_CONFIG_BYTES, "plan file")
                        .map_err(|e| {
                            err(
                                &p.display().to_string(),
                                format!("cannot read the plan: {e}"),
                                "check the path given to --plan",
                            )
                        })?;
                (
                    text,
                    p.display().to_string(),
                    p.parent().map(Path::to_path_buf),
                )
            }
        };
        Plan::parse(&text, &source, dir.as_deref(), pipeline)
    }

    /// Parses and checks a plan's text; `dir` resolves its `pipeline` key, `base` (a file)
    /// overrides it.
    pub fn parse(
        text: &str,
        file: &str,
        dir: Option<&Path>,
        base: Option<&Path>,
    ) -> Result<Plan, StudyError> {
        let doc: toml::Table = text
            .parse()
            .map_err(|e: toml::de::Error| err(file, e.to_string(), "fix the TOML syntax"))?;
        check_top_level_keys(&doc, file)?;
        let empty = toml::Table::new();
        let study = study_table(&doc, file)?.unwrap_or(&empty);
        let (base_pipeline, base_name, base_doc) = load_base(study, file, dir, base)?;
        let held_out = held_out(study, file)?;
        let limits = StudyLimits::read(study, file)?;
        let cells = grid_cells(&doc, file, &base_doc, &base_name)?;
        let rows_dir = dir
            .map(Path::to_path_buf)
            .unwrap_or_else(|| crate::config::source_tree().join("pipelines"));
        let simulator = simulator_specs(&doc, file, &rows_dir)?;
        let contact = contact_specs(&doc, file)?;
        Ok(Plan {
            base_pipeline,
            simulator,
            contact,
            source: file.to_string(),
            text: text.to_string(),
            base: base_name,
            held_out,
            max_cells: limits.max_cells,
            max_minutes: limits.max_minutes,
            eval_points: limits.eval_points,
            cells,
        })
    }
}

/// A plan's top-level keys are `study`, `grid`, `simulator` and `contact`.
fn check_top_level_keys(doc: &toml::Table, file: &str) -> Result<(), StudyError> {
    for k in doc.keys() {
        if !["study", "grid", "simulator", "contact"].contains(&k.as_str()) {
            return Err(err(
                file,
                format!("unknown top-level key `{k}`"),
                "a plan has a [study] table, [[grid]] tables and optionally [[simulator]] and [[contact]] tables",
            ));
        }
    }
    Ok(())
}

/// The `[study]` table (`None` when absent), holding only [`STUDY_KEYS`].
fn study_table<'a>(
    doc: &'a toml::Table,
    file: &str,
) -> Result<Option<&'a toml::Table>, StudyError> {
    let study = match doc.get("study") {
        None => return Ok(None),
        Some(toml::Value::Table(t)) => t,
        Some(_) => return Err(err(file, "`study` is not a table", "write [study]")),
    };
    let allowed: Vec<&str> = STUDY_KEYS.iter().map(|(k, _)| *k).collect();
    for k in study.keys() {
        if !allowed.contains(&k.as_str()) {
            return Err(err(
                file,
                format!("unknown key study.{k}"),
                format!("[study] takes {}", allowed.join(", ")),
            ));
        }
    }
    Ok(Some(study))
}

/// The base pipeline: --pipeline (`base`), the plan's key (relative to the plan's `dir`), or
/// the embedded default; read and checked by the pipeline's own loader (its text is what the
/// cells patch). Returns it with its name and its text as a TOML table.
fn load_base(
    study: &toml::Table,
    file: &str,
    dir: Option<&Path>,
    base: Option<&Path>,
) -> Result<(Pipeline, String, toml::Table), StudyError> {
    let path = match (base, study.get("pipeline")) {
        (Some(p), _) => Some(p.to_path_buf()),
        (None, None) => None,
        (None, Some(toml::Value::String(s))) => Some(match dir {
            Some(d) => d.join(s),
            None => crate::config::source_tree().join("pipelines").join(s),
        }),
        (None, Some(v)) => {
            return Err(err(
                file,
                format!("study.pipeline = {v}: not a file name"),
                "give the pipeline file as a string, relative to the plan",
            ))
        }
    };
    let base_pipeline = Pipeline::load(path.as_deref()).map_err(|e| {
        err(
            file,
            format!("base pipeline: {e}"),
            "fix the pipeline the plan names (study.pipeline is relative to the plan; --pipeline overrides it)",
        )
    })?;
    let base_name = base_pipeline.source.clone();
    let base_doc: toml::Table = base_pipeline.text.parse().map_err(|e: toml::de::Error| {
        err(&base_name, e.to_string(), "fix the pipeline's TOML syntax")
    })?;
    Ok((base_pipeline, base_name, base_doc))
}

/// `study.held_out`: the names of the runs scored and never trained on (`None` when absent).
fn held_out(study: &toml::Table, file: &str) -> Result<Option<Vec<String>>, StudyError> {
    Ok(match study.get("held_out") {
        None => None,
        Some(toml::Value::Array(a)) => {
            let mut names = Vec::new();
            for v in a {
                match v {
                    toml::Value::String(s) => names.push(s.clone()),
                    _ => {
                        return Err(err(
                            file,
                            format!("study.held_out: {v} is not a run name"),
                            "give run names as strings, e.g. [\"soap_120kmh_0c\"]",
                        ))
                    }
                }
            }
            Some(names)
        }
        Some(v) => {
            return Err(err(
                file,
                format!("study.held_out = {v}: not a list"),
                "give a list of run names",
            ))
        }
    })
}

/// The limits of `[study]`.
struct StudyLimits {
    max_cells: usize,
    eval_points: usize,
    max_minutes: f64,
}

impl StudyLimits {
    /// `study.max_cells`, `study.eval_points` and `study.max_minutes`, checked in this order.
    fn read(study: &toml::Table, file: &str) -> Result<StudyLimits, StudyError> {
        let int = |key: &str, default: i64, lo: i64, hi: i64| -> Result<i64, StudyError> {
            match study.get(key) {
                None => Ok(default),
                Some(toml::Value::Integer(i)) if (lo..=hi).contains(i) => Ok(*i),
                Some(v) => Err(err(
                    file,
                    format!("study.{key} = {v}"),
                    format!("give a whole number in {lo}..={hi}"),
                )),
            }
        };
        let max_cells = int("max_cells", 200, 1, 100_000)? as usize;
        let eval_points = int("eval_points", 4096, 16, 1 << 20)? as usize;
        let max_minutes = match study.get("max_minutes") {
            None => 30.0,
            Some(toml::Value::Integer(i)) if *i > 0 => *i as f64,
            Some(toml::Value::Float(f)) if f.is_finite() && *f > 0.0 => *f,
            Some(v) => {
                return Err(err(
                    file,
                    format!("study.max_minutes = {v}"),
                    "give a positive number of minutes",
                ))
            }
        };
        Ok(StudyLimits {
            max_cells,
            eval_points,
            max_minutes,
        })
    }
}

/// The cells of the plan's `[[grid]]` tables (at least one), grid by grid, a cell of the same
/// family and pipeline as an earlier one left out.
fn grid_cells(
    doc: &toml::Table,
    file: &str,
    base_doc: &toml::Table,
    base_name: &str,
) -> Result<Vec<CellSpec>, StudyError> {
    let grids: &[toml::Value] = match doc.get("grid") {
        None => &[],
        Some(toml::Value::Array(a)) => a,
        Some(_) => {
            return Err(err(
                file,
                "`grid` is not a list of tables",
                "write each grid as [[grid]]",
            ))
        }
    };
    if grids.is_empty() {
        return Err(err(
            file,
            "the plan has no [[grid]]: nothing to study",
            "add a [[grid]] with train.model = [\"mlp\"] and the keys to vary (docs/study.md)",
        ));
    }
    let mut cells: Vec<CellSpec> = Vec::new();
    let mut seen = std::collections::HashSet::new();
    for (g, grid) in grids.iter().enumerate() {
        let toml::Value::Table(grid) = grid else {
            return Err(err(
                file,
                format!("grid[{g}] is not a table"),
                "write [[grid]]",
            ));
        };
        for spec in expand(grid, g, file, base_doc, base_name)? {
            let key = (spec.family.name(), spec.pipeline.text.clone());
            if seen.insert(key) {
                cells.push(spec);
            }
        }
    }
    Ok(cells)
}

/// The cells of one grid: the product of its axes, family by family.
fn expand(
    grid: &toml::Table,
    g: usize,
    file: &str,
    base: &toml::Table,
    base_name: &str,
) -> Result<Vec<CellSpec>, StudyError> {
    let at = format!("grid[{g}]");
    let spec = GridSpec::read(grid, g, &at, file)?;
    let combos = product(&spec.axes);
    let mut out = Vec::new();
    for family in spec.families {
        for combo in &combos {
            out.push(CellSpec {
                group: spec.label.clone(),
                family,
                settings: combo
                    .iter()
                    .map(|(k, v)| (k.clone(), short(k, v)))
                    .collect(),
                pipeline: cell_pipeline(base, combo, true, file, &at, base_name)?,
                conditioning: cell_pipeline(base, combo, false, file, &at, base_name)?,
            });
        }
    }
    Ok(out)
}

/// What one `[[grid]]` table says.
struct GridSpec {
    /// `label` (default `grid N`).
    label: String,
    /// `train.model` (default the network).
    families: Vec<&'static dyn ModelFamily>,
    /// Axes in key order: (pipeline key, values).
    axes: BTreeMap<String, Vec<toml::Value>>,
}

impl GridSpec {
    /// Reads grid `g` (named `at` in messages), key by key.
    fn read(grid: &toml::Table, g: usize, at: &str, file: &str) -> Result<GridSpec, StudyError> {
        let mut spec = GridSpec {
            label: format!("grid {g}"),
            families: vec![&Network],
            axes: BTreeMap::new(),
        };
        for (k, v) in grid {
            match (k.as_str(), v) {
                ("label", toml::Value::String(s)) => spec.label = s.clone(),
                ("label", v) => {
                    return Err(err(
                        file,
                        format!("{at}.label = {v}: not text"),
                        "give a short name in quotes",
                    ))
                }
                ("family", _) => {
                    return Err(err(
                        file,
                        format!("{at}: family is now train.model"),
                        "write train.model = [\"mlp\", \"residual\", \"polach\", …] (a pipeline's train.model values, plus \"polach_pooled\" for the old family \"polach\" and \"polach_kt\"; docs/study.md)",
                    ))
                }
                (section, toml::Value::Table(t)) if GRID_SECTIONS.contains(&section) => {
                    section_axes(section, t, at, file, &mut spec.axes)?
                }
                (other, _) => {
                    return Err(err(
                        file,
                        format!("{at}: unknown key {other}"),
                        format!(
                            "a grid takes label and the pipeline sections {} (train.model: the model a cell fits)",
                            GRID_SECTIONS.join(", ")
                        ),
                    ))
                }
            }
        }
        // The model axis: a cell fits the one model its train.model names.
        if let Some(models) = spec.axes.remove("train.model") {
            spec.families = grid_families(&models, at, file)?;
        }
        // train.folds sets how a campaign's choice among models is scored; a cell has none.
        if spec.axes.contains_key("train.folds") {
            return Err(err(
                file,
                format!("{at}: train.folds scores a campaign's choice among models; a study cell fits the one model its train.model names"),
                "leave train.folds out of the grid (a study scores every cell on its held-out runs)",
            ));
        }
        Ok(spec)
    }
}

/// A grid's `train.model` values (at least one), each a name of [`FAMILIES`]; `auto` (a
/// campaign's choice among models) is refused with the names to list instead.
fn grid_families(
    vals: &[toml::Value],
    at: &str,
    file: &str,
) -> Result<Vec<&'static dyn ModelFamily>, StudyError> {
    let names = || {
        FAMILIES
            .iter()
            .map(|f| format!("\"{}\"", f.name()))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let mut families = Vec::new();
    for f in vals {
        let name = f.as_str().unwrap_or("");
        match by_name(name) {
            Some(x) => families.push(x),
            None if name == "auto" => {
                return Err(err(
                    file,
                    format!("{at}.train.model = \"auto\": a study cell fits one model, not a campaign's choice among them"),
                    format!("list the candidates to compare: {}", names()),
                ))
            }
            None => {
                return Err(err(
                    file,
                    format!("{at}.train.model: unknown model {f}"),
                    format!("a grid's train.model is one of {}", names()),
                ));
            }
        }
    }
    Ok(families)
}

/// The pipeline keys of `section` (`train.layers`, …).
fn pipeline_keys(section: &str) -> Vec<&'static str> {
    crate::config::SECTIONS
        .iter()
        .filter(|(s, _)| *s == section)
        .flat_map(|(_, keys)| keys.iter().map(|k| k.name))
        .collect()
}

/// The axes a grid's pipeline section `t` (`[grid.train]`, …) adds to `axes`, one per key,
/// each a pipeline key of the section.
fn section_axes(
    section: &str,
    t: &toml::Table,
    at: &str,
    file: &str,
    axes: &mut BTreeMap<String, Vec<toml::Value>>,
) -> Result<(), StudyError> {
    let known = pipeline_keys(section);
    for (key, v) in t {
        let full = format!("{section}.{key}");
        if !known.contains(&full.as_str()) {
            return Err(err(
                file,
                format!("{at}: unknown key {full}"),
                format!("[{section}] keys are {}", known.join(", ")),
            ));
        }
        let vals = axis_values(&full, v, at, file)?;
        axes.insert(full, vals);
    }
    Ok(())
}

/// The values of the axis of pipeline key `full`: a list (of lists for a key whose value is
/// a list), or a single value as one cell; never empty.
fn axis_values(
    full: &str,
    v: &toml::Value,
    at: &str,
    file: &str,
) -> Result<Vec<toml::Value>, StudyError> {
    let vals = match v {
        toml::Value::Array(a) => {
            if LIST_KEYS.contains(&full) && a.iter().any(|x| !matches!(x, toml::Value::Array(_))) {
                return Err(err(
                    file,
                    format!(
                        "{at}.{full} = {v}: {full} takes a list, so the grid takes a list of lists"
                    ),
                    format!("write {full} = [{v}] for one cell, or e.g. [[10], [20]] for two"),
                ));
            }
            a.clone()
        }
        v => vec![v.clone()],
    };
    if vals.is_empty() {
        return Err(err(
            file,
            format!("{at}.{full} = []: an empty list makes no cells"),
            "give at least one value",
        ));
    }
    Ok(vals)
}

/// The Cartesian product of the axes, first axis slowest: every combination of one value
/// per axis, as (pipeline key, value) in key order.
fn product(axes: &BTreeMap<String, Vec<toml::Value>>) -> Vec<Vec<(String, toml::Value)>> {
    let mut combos: Vec<Vec<(String, toml::Value)>> = vec![vec![]];
    for (k, vals) in axes {
        combos = combos
            .into_iter()
            .flat_map(|c| {
                vals.iter().map(move |v| {
                    let mut c = c.clone();
                    c.push((k.clone(), v.clone()));
                    c
                })
            })
            .collect();
    }
    combos
}

/// The base pipeline `base` with `combo`'s keys set (without its `[train]` keys unless
/// `train`: the conditioning pipeline), checked by the pipeline's own rules.
fn cell_pipeline(
    base: &toml::Table,
    combo: &[(String, toml::Value)],
    train: bool,
    file: &str,
    at: &str,
    base_name: &str,
) -> Result<Pipeline, StudyError> {
    let mut doc = base.clone();
    for (k, v) in combo {
        let (section, key) = k.split_once('.').expect("section.key");
        if section == "train" && !train {
            continue;
        }
        let entry = doc
            .entry(section.to_string())
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        if let toml::Value::Table(t) = entry {
            // `hidden` and `layers` say the same thing; the pipeline refuses both.
            match key {
                "layers" => t.remove("hidden"),
                "hidden" => t.remove("layers"),
                _ => None,
            };
            t.insert(key.to_string(), v.clone());
        }
    }
    let text = toml::to_string(&doc)
        .map_err(|e| err(file, format!("{at}: {e}"), "report this as a bug"))?;
    let name = format!("{base_name} with {at} {}", show(combo));
    Pipeline::from_toml(&text, &name).map_err(|e| {
        err(
            file,
            format!("{at}: {e}"),
            "change the grid's value to one the pipeline accepts (docs/pipeline.md)",
        )
    })
}

fn show(combo: &[(String, toml::Value)]) -> String {
    combo
        .iter()
        .map(|(k, v)| format!("{k} = {v}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// A value as a cell name shows it (`train.inputs` by its count).
fn short(key: &str, v: &toml::Value) -> String {
    match (key, v) {
        ("train.inputs", toml::Value::Array(a)) => a.len().to_string(),
        (_, toml::Value::String(s)) => s.clone(),
        (_, v) => v.to_string(),
    }
}

/// The `[[name]]` tables of a plan (none when absent).
fn tables<'a>(
    doc: &'a toml::Table,
    name: &str,
    file: &str,
) -> Result<Vec<&'a toml::Table>, StudyError> {
    match doc.get(name) {
        None => Ok(vec![]),
        Some(toml::Value::Array(a)) => a
            .iter()
            .enumerate()
            .map(|(i, v)| match v {
                toml::Value::Table(t) => Ok(t),
                _ => Err(err(
                    file,
                    format!("{name}[{i}] is not a table"),
                    format!("write [[{name}]]"),
                )),
            })
            .collect(),
        Some(_) => Err(err(
            file,
            format!("`{name}` is not a list of tables"),
            format!("write [[{name}]]"),
        )),
    }
}

fn check_keys(t: &toml::Table, at: &str, allowed: &[&str], file: &str) -> Result<(), StudyError> {
    for k in t.keys() {
        if !allowed.contains(&k.as_str()) {
            return Err(err(
                file,
                format!("{at}: unknown key {k}"),
                format!("{at} takes {}", allowed.join(", ")),
            ));
        }
    }
    Ok(())
}

/// A number or a list of numbers.
fn numbers(v: &toml::Value, what: &str, file: &str) -> Result<Vec<f64>, StudyError> {
    let one = |x: &toml::Value| match x {
        toml::Value::Integer(i) => Ok(*i as f64),
        toml::Value::Float(f) if f.is_finite() => Ok(*f),
        _ => Err(err(
            file,
            format!("{what} = {v}: not a number"),
            "give a number or a list of numbers",
        )),
    };
    let vals = match v {
        toml::Value::Array(a) => a.iter().map(one).collect::<Result<Vec<_>, _>>()?,
        x => vec![one(x)?],
    };
    if vals.is_empty() {
        return Err(err(
            file,
            format!("{what} = []: an empty list makes no rows"),
            "give at least one value",
        ));
    }
    Ok(vals)
}

fn strings(
    v: &toml::Value,
    what: &str,
    allowed: &[&str],
    file: &str,
) -> Result<Vec<String>, StudyError> {
    let vals: Vec<&toml::Value> = match v {
        toml::Value::Array(a) => a.iter().collect(),
        x => vec![x],
    };
    if vals.is_empty() {
        return Err(err(
            file,
            format!("{what} = []: an empty list makes no rows"),
            "give at least one value",
        ));
    }
    vals.into_iter()
        .map(|x| match x.as_str() {
            Some(s) if allowed.contains(&s) => Ok(s.to_string()),
            _ => Err(err(
                file,
                format!("{what}: unknown value {x}"),
                format!("give one of {}", allowed.join(", ")),
            )),
        })
        .collect()
}

fn simulator_specs(doc: &toml::Table, file: &str, dir: &Path) -> Result<Vec<SimSpec>, StudyError> {
    let mut out = Vec::new();
    for (i, t) in tables(doc, "simulator", file)?.into_iter().enumerate() {
        let at = format!("simulator[{i}]");
        check_keys(t, &at, &["scene", "step_ms", "reference_step_ms"], file)?;
        let (scene, scene_name) = match t.get("scene") {
            Some(toml::Value::String(s)) => (dir.join(s), s.clone()),
            _ => {
                return Err(err(file, format!("{at}.scene is missing"), "give a scene file, relative to the plan, e.g. scene = \"scenes/soap_120kmh_p20.toml\""))
            }
        };
        let steps = numbers(
            t.get("step_ms").ok_or_else(|| {
                err(
                    file,
                    format!("{at}.step_ms is missing"),
                    "give the steps to compare, e.g. [0.05, 0.1, 0.2]",
                )
            })?,
            &format!("{at}.step_ms"),
            file,
        )?;
        let reference_step_ms = match t.get("reference_step_ms") {
            None => 0.02,
            Some(v) => numbers(v, &format!("{at}.reference_step_ms"), file)?[0],
        };
        let text =
            crate::input::read_text_limited(&scene, crate::input::MAX_CONFIG_BYTES, "scene file")
                .map_err(|e| {
                err(
                    file,
                    format!("{at}.scene {}: {e}", scene.display()),
                    "give an existing scene file, relative to the plan",
                )
            })?;
        let doc: toml::Table = text.parse().map_err(|e: toml::de::Error| {
            err(
                file,
                format!("{at}.scene {}: {e}", scene.display()),
                "fix the scene's TOML",
            )
        })?;
        let with_step = |step: f64| -> Result<Scene, StudyError> {
            let mut d = doc.clone();
            let run = d
                .entry("run".to_string())
                .or_insert_with(|| toml::Value::Table(toml::Table::new()));
            if let toml::Value::Table(r) = run {
                r.insert("step_ms".into(), toml::Value::Float(step));
            }
            let text = toml::to_string(&d)
                .map_err(|e| err(file, format!("{at}: {e}"), "report this as a bug"))?;
            Scene::from_toml(
                &text,
                &format!("{} with run.step_ms = {step}", scene.display()),
                scene.parent(),
            )
            .map_err(|e| {
                err(
                    file,
                    format!("{at}: {e}"),
                    "choose steps the scene accepts (run.step_ms, docs/simulator.md#scene-file)",
                )
            })
        };
        out.push(SimSpec {
            steps: steps
                .iter()
                .map(|&s| Ok((s, with_step(s)?)))
                .collect::<Result<_, StudyError>>()?,
            reference: with_step(reference_step_ms)?,
            reference_step_ms,
            scene_file: scene,
            scene_name,
        });
    }
    Ok(out)
}

fn contact_specs(doc: &toml::Table, file: &str) -> Result<Vec<ContactSpec>, StudyError> {
    use crate::contact::fastsim::Bound;
    let mut out = Vec::new();
    for (i, t) in tables(doc, "contact", file)?.into_iter().enumerate() {
        let at = format!("contact[{i}]");
        check_keys(
            t,
            &at,
            &[
                "law",
                "grid",
                "bound",
                "reference_grid",
                "mu",
                "creepage_max",
            ],
            file,
        )?;
        let laws = match t.get("law") {
            None => vec!["fastsim".to_string()],
            Some(v) => strings(v, &format!("{at}.law"), &CONTACT_LAWS, file)?,
        };
        let grid_of = |v: f64, what: &str| -> Result<usize, StudyError> {
            if v.fract() == 0.0 && (1.0..=1000.0).contains(&v) {
                Ok(v as usize)
            } else {
                Err(err(
                    file,
                    format!("{what} = {v}"),
                    "give cells per side as whole numbers in 1..=1000",
                ))
            }
        };
        let grids = match t.get("grid") {
            None => vec![10, 20, 50],
            Some(v) => numbers(v, &format!("{at}.grid"), file)?
                .into_iter()
                .map(|g| grid_of(g, &format!("{at}.grid")))
                .collect::<Result<_, _>>()?,
        };
        let reference_grid = match t.get("reference_grid") {
            None => 400,
            Some(v) => grid_of(
                numbers(v, &format!("{at}.reference_grid"), file)?[0],
                &format!("{at}.reference_grid"),
            )?,
        };
        let bounds = match t.get("bound") {
            None => vec![Bound::Elliptic],
            Some(v) => strings(v, &format!("{at}.bound"), &["elliptic", "parabolic"], file)?
                .iter()
                .map(|b| {
                    if b == "elliptic" {
                        Bound::Elliptic
                    } else {
                        Bound::Parabolic
                    }
                })
                .collect(),
        };
        let num = |key: &str, default: f64, lo: f64, hi: f64| -> Result<f64, StudyError> {
            match t.get(key) {
                None => Ok(default),
                Some(v) => {
                    let x = numbers(v, &format!("{at}.{key}"), file)?[0];
                    if x > lo && x <= hi {
                        Ok(x)
                    } else {
                        Err(err(
                            file,
                            format!("{at}.{key} = {x}"),
                            format!("give a value in ({lo}, {hi}]"),
                        ))
                    }
                }
            }
        };
        out.push(ContactSpec {
            laws,
            grids,
            bounds,
            reference_grid,
            mu: num("mu", 0.3, 0.0, 1.5)?,
            creepage_max: num("creepage_max", 0.01, 0.0, 1.0)?,
        });
    }
    Ok(out)
}
