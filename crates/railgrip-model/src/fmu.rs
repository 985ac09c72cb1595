//! The text of an FMI 2.0 Functional Mock-up Unit around a model file: `modelDescription.xml`,
//! the FMI wrapper `fmu.c` (Model Exchange and Co-Simulation, every function the standard
//! requires; the C text lives in `c/fmi2.c.in`) and `model.h`, the model's header-only C
//! evaluator ([`crate::c_header`]). Packaging (the zip, the compiled binary) is the pipeline
//! library's (`railgrip::fmu`); this module only writes text.
//!
//! The FMU's variables are the inputs the model's μ depends on, in this order and with these
//! value references: `dv_mps` (slip Δv, m/s), `ddv_mps2` (slip rate dΔv/dt, m/s², networks
//! only), `v_mps` (speed, m/s: every kind uses it, networks for the creep slope and as the
//! third input, Polach models for the creepage), `ambient_temperature_c` (°C, when the model
//! has a temperature input or law), then the output `mu`. The inputs' start values are the
//! file's own: Δv and dΔv/dt 0, the reference speed, the reference temperature (for a law
//! without one, the middle of its fitted range; NaN, the law's base values, is accepted as an
//! input but not written as a start). The training domain is stated in each
//! input's description as a nominal range, not as `min`/`max` an importer would enforce (μ is
//! odd in Δv, and outside the domain the file's rule applies).

use super::c_header::{c_header, comment_text, fill, lit};
use super::{ModelFile, ModelKind};

/// The prefix of the model header's symbols inside an FMU (`railgrip_model_mu_vt`, …).
pub const HEADER_PREFIX: &str = "railgrip_model";

/// One variable of an FMU.
#[derive(Debug, Clone, PartialEq)]
pub struct FmuVariable {
    /// Its name in `modelDescription.xml` (an estimates-table column name, or `mu`).
    pub name: &'static str,
    pub value_reference: u32,
    /// The FMI unit (`m/s`, `m/s2`, `degC`, `1`).
    pub unit: &'static str,
    /// What it is, its training domain (nominal range) and what NaN means.
    pub description: String,
    /// Start value (inputs only).
    pub start: Option<f64>,
    /// Which argument of the evaluator's `mu_vt(dv, ddv, v, t)` it is (inputs only).
    pub arg: usize,
}

/// The text of an FMU's files.
#[derive(Debug, Clone)]
pub struct FmuText {
    pub model_description: String,
    /// `sources/fmu.c`: the FMI functions; includes `model.h`.
    pub fmu_c: String,
    /// `sources/model.h`: the model's evaluator.
    pub model_h: String,
    /// The inputs in value-reference order, then the output.
    pub variables: Vec<FmuVariable>,
}

/// The FMI wrapper's C text with its placeholders (part of what an FMU's GUID is made from:
/// another wrapper, another GUID).
pub const WRAPPER_TEMPLATE: &str = include_str!("c/fmi2.c.in");

/// A `[lo, hi]` range as text, or nothing when unknown.
fn range(r: Option<(f64, f64)>, unit: &str) -> String {
    match r {
        Some((lo, hi)) => format!(
            "; training domain {lo:.6} to {hi:.6} {unit} (a nominal range: outside it the model file's rule applies)"
        ),
        None => String::new(),
    }
}

/// The FMU's inputs for model `m`, in value-reference order.
pub fn fmu_inputs(m: &ModelFile) -> Vec<FmuVariable> {
    let domain = |name: &str| {
        m.inputs
            .iter()
            .find(|i| i.name == name)
            .map(|i| (i.domain_min, i.domain_max))
    };
    let v_ref = m
        .creep
        .as_ref()
        .map(|c| c.reference_speed_mps)
        .or_else(|| m.polach.as_ref().map(|p| p.reference_speed_mps))
        .unwrap_or(f64::NAN);
    let t_ref = m
        .creep
        .as_ref()
        .and_then(|c| c.reference_temperature_c)
        .unwrap_or(f64::NAN);
    let law_t = m
        .polach
        .as_ref()
        .or(m.base.as_ref())
        .and_then(|p| p.temperature.as_ref());
    let has_t = domain("ambient_temperature_c").is_some() || law_t.is_some();
    let mut out = vec![FmuVariable {
        name: "dv_mps",
        value_reference: 0,
        unit: "m/s",
        description: format!(
            "slip velocity dv = v - omega r (m/s; mu is odd in it){}",
            range(domain("dv_mps"), "m/s")
        ),
        start: Some(0.0),
        arg: 0,
    }];
    if m.kind == ModelKind::Mlp {
        out.push(FmuVariable {
            name: "ddv_mps2",
            value_reference: 0,
            unit: "m/s2",
            description: format!(
                "slip rate d(dv)/dt (m/s2){}",
                range(domain("ddv_mps2"), "m/s2")
            ),
            start: Some(0.0),
            arg: 1,
        });
    }
    out.push(FmuVariable {
        name: "v_mps",
        value_reference: 0,
        unit: "m/s",
        description: format!(
            "vehicle speed (m/s); NaN means the reference speed {v_ref:.6} m/s{}",
            range(domain("v_mps"), "m/s")
        ),
        start: Some(v_ref),
        arg: 2,
    });
    if has_t {
        let r = domain("ambient_temperature_c")
            .or_else(|| law_t.map(|t| (t.fitted_range_c[0], t.fitted_range_c[1])));
        // A finite start (tools that write Modelica wrappers have no NaN literal): the
        // reference temperature, or for a law without one the middle of its fitted range.
        let (what, start) = if t_ref.is_nan() {
            let mid = r.map_or(20.0, |(lo, hi)| 0.5 * (lo + hi));
            (
                format!("NaN means the law's base values (no temperature); start {mid:.6} C, the middle of the fitted range"),
                mid,
            )
        } else {
            (
                format!("NaN means the reference temperature {t_ref:.6} C, the start value"),
                t_ref,
            )
        };
        out.push(FmuVariable {
            name: "ambient_temperature_c",
            value_reference: 0,
            unit: "degC",
            description: format!("ambient temperature (C); {what}{}", range(r, "C")),
            start: Some(start),
            arg: 3,
        });
    }
    for (k, v) in out.iter_mut().enumerate() {
        v.value_reference = k as u32;
    }
    out
}

/// `s` as XML attribute text.
fn attr(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            c if c.is_control() => out.push(' '),
            c => out.push(c),
        }
    }
    out
}

/// What the model is, in one line: kind, shape, training data, generation.
pub fn describe(m: &ModelFile) -> String {
    let what = match m.kind {
        ModelKind::Mlp if m.base.is_some() => {
            format!("residual network {} over a Polach law", m.architecture())
        }
        ModelKind::Mlp => format!("tanh network {}", m.architecture()),
        ModelKind::Polach => {
            let p = m.polach.as_ref();
            format!(
                "Polach model{}{}",
                if p.and_then(|p| p.temperature.as_ref()).is_some() {
                    " with a temperature law"
                } else {
                    ""
                },
                if p.and_then(|p| p.speed.as_ref()).is_some() {
                    " and a speed law"
                } else {
                    ""
                }
            )
        }
    };
    let pv = &m.provenance;
    format!(
        "railgrip adhesion model: {what}, trained on {} input file(s) (pipeline {}, SHA-256 {}, seed {}), generation {}, railgrip {}{}; outside the training domain: {}",
        pv.inputs.len(),
        pv.pipeline,
        pv.pipeline_sha256,
        pv.seed,
        pv.generation.as_deref().unwrap_or("none"),
        pv.crate_version,
        if pv.created.is_empty() { String::new() } else { format!(", created {}", pv.created) },
        m.outside_domain
    )
}

/// The FMU text for model `m` (checked) under `model_identifier` (a C identifier: the shared
/// library's name), with `guid` (the model's fingerprint), `source` (the model file's name,
/// for comments) and `tool` (`railgrip <version>`).
pub fn fmu_text(
    m: &ModelFile,
    model_identifier: &str,
    guid: &str,
    source: &str,
    tool: &str,
) -> FmuText {
    let inputs = fmu_inputs(m);
    let n = inputs.len();
    let mu = FmuVariable {
        name: "mu",
        value_reference: n as u32,
        unit: "1",
        description: "adhesion coefficient mu = tangential / normal force (-)".into(),
        start: None,
        arg: 0,
    };
    let description = describe(m);
    let mut xml = String::new();
    xml.push_str("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
    xml.push_str(&format!(
        "<fmiModelDescription fmiVersion=\"2.0\" modelName=\"{id}\" guid=\"{guid}\"\n  description=\"{d}\"\n  generationTool=\"{tool}\" variableNamingConvention=\"flat\" numberOfEventIndicators=\"0\">\n",
        id = attr(model_identifier),
        guid = attr(guid),
        d = attr(&description),
        tool = attr(tool),
    ));
    let caps = "canGetAndSetFMUstate=\"true\" canSerializeFMUstate=\"true\"";
    xml.push_str(&format!(
        "  <ModelExchange modelIdentifier=\"{id}\" completedIntegratorStepNotNeeded=\"true\" {caps}>\n    <SourceFiles><File name=\"fmu.c\"/></SourceFiles>\n  </ModelExchange>\n",
        id = attr(model_identifier)
    ));
    xml.push_str(&format!(
        "  <CoSimulation modelIdentifier=\"{id}\" canHandleVariableCommunicationStepSize=\"true\" {caps}>\n    <SourceFiles><File name=\"fmu.c\"/></SourceFiles>\n  </CoSimulation>\n",
        id = attr(model_identifier)
    ));
    xml.push_str(
        "  <UnitDefinitions>\n    <Unit name=\"m/s\"><BaseUnit m=\"1\" s=\"-1\"/></Unit>\n    <Unit name=\"m/s2\"><BaseUnit m=\"1\" s=\"-2\"/></Unit>\n    <Unit name=\"degC\"><BaseUnit K=\"1\" offset=\"273.15\"/></Unit>\n    <Unit name=\"1\"/>\n  </UnitDefinitions>\n",
    );
    xml.push_str(
        "  <LogCategories>\n    <Category name=\"logStatusError\" description=\"inputs the model cannot take (a NaN or infinite slip or slip rate) and calls this FMU does not support\"/>\n  </LogCategories>\n",
    );
    xml.push_str("  <ModelVariables>\n");
    for v in &inputs {
        xml.push_str(&format!(
            "    <ScalarVariable name=\"{}\" valueReference=\"{}\" description=\"{}\" causality=\"input\" variability=\"continuous\">\n      <Real unit=\"{}\" start=\"{:?}\"/>\n    </ScalarVariable>\n",
            v.name,
            v.value_reference,
            attr(&v.description),
            v.unit,
            v.start.unwrap_or(f64::NAN)
        ));
    }
    xml.push_str(&format!(
        "    <ScalarVariable name=\"mu\" valueReference=\"{n}\" description=\"{}\" causality=\"output\" variability=\"continuous\" initial=\"calculated\">\n      <Real unit=\"1\"/>\n    </ScalarVariable>\n",
        attr(&mu.description)
    ));
    xml.push_str("  </ModelVariables>\n");
    let deps = (1..=n).map(|i| i.to_string()).collect::<Vec<_>>().join(" ");
    xml.push_str(&format!(
        "  <ModelStructure>\n    <Outputs><Unknown index=\"{o}\" dependencies=\"{deps}\"/></Outputs>\n    <InitialUnknowns><Unknown index=\"{o}\" dependencies=\"{deps}\"/></InitialUnknowns>\n  </ModelStructure>\n</fmiModelDescription>\n",
        o = n + 1
    ));

    let vars = inputs
        .iter()
        .chain(std::iter::once(&mu))
        .map(|v| format!("{} {} [{}]", v.value_reference, v.name, v.unit))
        .collect::<Vec<_>>()
        .join(", ");
    let join =
        |f: &dyn Fn(&FmuVariable) -> String| inputs.iter().map(f).collect::<Vec<_>>().join(", ");
    let mut names: Vec<String> = inputs.iter().map(|v| format!("\"{}\"", v.name)).collect();
    names.push("\"mu\"".into());
    let fmu_c = fill(
        WRAPPER_TEMPLATE,
        &[
            ("id", comment_text(model_identifier)),
            ("version", comment_text(tool)),
            ("source", comment_text(source)),
            ("what", comment_text(&description)),
            ("vars", comment_text(&vars)),
            ("P", HEADER_PREFIX.to_uppercase()),
            ("p", HEADER_PREFIX.to_string()),
            // A GUID is hex digits and dashes in braces: nothing to escape in a C string.
            ("guid", guid.to_string()),
            ("n_in", n.to_string()),
            ("vr_mu", n.to_string()),
            ("args", join(&|v| v.arg.to_string())),
            ("starts", join(&|v| lit(v.start.unwrap_or(f64::NAN)))),
            ("names", names.join(", ")),
        ],
    );
    FmuText {
        model_description: xml,
        fmu_c,
        model_h: c_header(m, HEADER_PREFIX, source),
        variables: inputs.into_iter().chain(std::iter::once(mu)).collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::attr;

    #[test]
    fn attribute_text_is_escaped() {
        assert_eq!(attr("a<b & \"c\"\n"), "a&lt;b &amp; &quot;c&quot; ");
    }
}
