//! A header-only C99 evaluator of a model file: the weights as `static const` arrays and the
//! evaluation of [`super::Model::mu_v`] step for step (same operations in the same order, so
//! with IEEE doubles and no FMA contraction the results agree with the Rust evaluator to the
//! last bit; a test compiles it with the system `cc` and checks 1e-12 on a grid). The C text
//! itself lives in `c/mlp.h.in` and `c/polach.h.in`, with `@name@` placeholders for the
//! model's numbers and the symbol prefix.

use super::polach::{stiffness, PolachSpec, CURTIUS_KNIFFLER_SPEED_MPS, MIN_SPEED_MPS};
use super::{CreepSpec, Layer, ModelFile, Scaling, SupportSpec, MAX_INPUTS};

/// Shortest decimal form that reads back to the same double (C's strtod rounds correctly);
/// every finite double, subnormals and ±1.7976931348623157e308 included, is a valid C
/// literal this way. A checked model file has no non-finite constant, but should one reach
/// here it is written as the C99 macro (`HUGE_VAL`, `NAN` from <math.h>), never as a bare
/// `inf` that does not compile.
pub(crate) fn lit(x: f64) -> String {
    if x.is_nan() {
        return "NAN".into();
    }
    if x.is_infinite() {
        return if x > 0.0 { "HUGE_VAL" } else { "(-HUGE_VAL)" }.into();
    }
    let s = format!("{x:?}");
    if s.contains('.') || s.contains('e') {
        s
    } else {
        format!("{s}.0")
    }
}

/// `s` made safe inside a C block comment (a model path holding
/// `*/ int injected_symbol = 1; /*` once compiled into the header): `*/` and `/*` broken
/// apart, control characters and backslashes (a line continuation) replaced by `?`.
pub(crate) fn comment_text(s: &str) -> String {
    let mut out: String = s
        .chars()
        .map(|c| if c.is_control() || c == '\\' { '?' } else { c })
        .collect();
    while out.contains("*/") || out.contains("/*") {
        out = out.replace("*/", "* /").replace("/*", "/ *");
    }
    out
}

/// `name [unit] in [min, max]` of every input, for the header comment.
fn inputs_line(m: &ModelFile) -> String {
    let line = m
        .inputs
        .iter()
        .map(|i| {
            format!(
                "{} [{}] in [{}, {}]",
                i.name,
                i.unit,
                lit(i.domain_min),
                lit(i.domain_max)
            )
        })
        .collect::<Vec<_>>()
        .join(", ");
    comment_text(&line)
}

fn array(name: &str, v: &[f64]) -> String {
    // C99 has no empty initialiser: an empty array is written as one unused 0.0.
    let items: Vec<String> = if v.is_empty() {
        vec!["0.0".into()]
    } else {
        v.iter().map(|x| lit(*x)).collect()
    };
    format!(
        "static const double {name}[{}] = {{\n    {}\n}};\n",
        v.len().max(1),
        items.join(",\n    ")
    )
}

/// The header text. `prefix` names the functions (`<prefix>_mu`, `<prefix>_mu_v`,
/// `<prefix>_mu_vt`, `<prefix>_mu_batch`, the same for every kind) and prefixes every symbol;
/// it must be a C identifier. `m` must be a checked file ([`ModelFile::read`] or a
/// constructor).
pub fn c_header(m: &ModelFile, prefix: &str, source: &str) -> String {
    match (&m.creep, &m.polach) {
        (Some(creep), _) => mlp_header(m, creep, prefix, source),
        (None, Some(p)) => polach_header(m, p, prefix, source),
        (None, None) => unreachable!("a checked model file has a creep or a polach section"),
    }
}

/// `template` with every `@name@` replaced by its value in `values` (a name missing from
/// `values` is a bug: the templates and this module change together; tested).
pub(crate) fn fill(template: &str, values: &[(&str, String)]) -> String {
    let mut out = String::with_capacity(template.len() * 2);
    let mut rest = template;
    while let Some(a) = rest.find('@') {
        out.push_str(&rest[..a]);
        let after = &rest[a + 1..];
        let b = after.find('@').expect("placeholders are closed");
        let name = &after[..b];
        let v = values
            .iter()
            .find(|(k, _)| *k == name)
            .unwrap_or_else(|| panic!("template placeholder @{name}@ has no value"));
        out.push_str(&v.1);
        rest = &after[b + 1..];
    }
    out.push_str(rest);
    out
}

/// The C text of the network evaluator (`c/mlp.h.in`).
const MLP_TEMPLATE: &str = include_str!("c/mlp.h.in");
/// The C text of the Polach evaluator (`c/polach.h.in`).
const POLACH_TEMPLATE: &str = include_str!("c/polach.h.in");

fn mlp_header(m: &ModelFile, creep: &CreepSpec, prefix: &str, source: &str) -> String {
    let k = m.inputs.len();
    let h = &m.layers[0];
    let o = m.layers.last().expect("checked: an output layer");
    let deep = &m.layers[1..m.layers.len() - 1];
    let scaling = m.scaling();
    let arrays = network_arrays(m, &scaling, prefix);
    let max_width = m.layers[..m.layers.len() - 1]
        .iter()
        .map(|l| l.biases.len())
        .max()
        .unwrap_or(1);
    let sup_arrays = match &m.support {
        None => String::new(),
        Some(sup) => support_arrays(sup, prefix),
    };
    fill(
        MLP_TEMPLATE,
        &[
            ("p", prefix.to_string()),
            ("P", prefix.to_uppercase()),
            (
                "guard",
                format!("{}_ADHESION_MODEL_H", prefix.to_uppercase()),
            ),
            (
                "v",
                match k {
                    4 => ", v, T",
                    3 => ", v",
                    _ => "",
                }
                .to_string(),
            ),
            ("ver", env!("CARGO_PKG_VERSION").to_string()),
            ("source", comment_text(source)),
            ("fmt", comment_text(&m.format)),
            ("fv", m.version.to_string()),
            ("nt", m.metrics.train_samples.to_string()),
            (
                "vm",
                m.metrics.val_mse.map(lit).unwrap_or_else(|| "n/a".into()),
            ),
            ("inputs", inputs_line(m)),
            ("k", k.to_string()),
            ("nh", h.shape[0].to_string()),
            ("ndeep", deep.len().to_string()),
            ("maxw", max_width.to_string()),
            ("arrays", arrays),
            ("b2", lit(o.biases[0] + 0.0)),
            ("expm1_p", railgrip_simd::EXPM1_P.map(lit).join(", ")),
            ("gy", lit(scaling.gy)),
            ("oy", lit(scaling.oy)),
            ("blend", lit(creep.blend_mps)),
            ("cpc", lit(creep.creep_stiffness_n / creep.wheel_load_n)),
            ("vref", lit(creep.reference_speed_mps)),
            // NaN without one, as the Rust evaluator: a residual network's law then takes its
            // base values (a plain network of fewer than 4 inputs ignores T).
            (
                "tref",
                lit(creep.reference_temperature_c.unwrap_or(f64::NAN)),
            ),
            ("has_sup", u8::from(m.support.is_some()).to_string()),
            ("sup_arrays", sup_arrays),
            ("has_base", u8::from(m.base.is_some()).to_string()),
            (
                "base",
                match &m.base {
                    None => String::new(),
                    Some(b) => base_law(m, b, prefix, source),
                },
            ),
            (
                "resid",
                if m.base.is_some() {
                    let outside = match &m.support {
                        None => "no grid: the network everywhere",
                        Some(s) if s.fallback == "law" => "0: the law alone",
                        Some(_) => "held along the slip rate",
                    };
                    format!("\n * A residual (grey-box) network: mu = the Polach law {prefix}_base_mu_vt(dv, 0, v, T)\n * plus the network, before the creep region; outside the data support the law plus the\n * fallback residual of the support grid ({outside}).")
                } else {
                    String::new()
                },
            ),
        ],
    )
}

/// A residual network's Polach law as C (`c/polach.h.in` with the prefix `<prefix>_base`),
/// placed in the network's header before the network.
fn base_law(m: &ModelFile, p: &PolachSpec, prefix: &str, source: &str) -> String {
    let pre = format!("{prefix}_base");
    let inputs = if p.temperature.is_some() {
        "dv_mps [m/s], v_mps [m/s], ambient_temperature_c [°C] (as the network's)"
    } else {
        "dv_mps [m/s], v_mps [m/s] (as the network's)"
    };
    let text = polach_text(
        p,
        &pre,
        &[
            (
                "source",
                format!("the base law of {}", comment_text(source)),
            ),
            ("fmt", comment_text(&m.format)),
            ("fv", m.version.to_string()),
            ("nt", m.metrics.train_samples.to_string()),
            ("rmse", "(see the network)".into()),
            ("inputs", inputs.into()),
        ],
    );
    format!("\n{text}\n")
}

/// The network's constant arrays (`@arrays@` of `c/mlp.h.in`): the input domain and
/// mapminmax (`_lo`, `_hi`, `_gx`, `_ox`), the first hidden layer (`_w1c` column-major, `_b1`),
/// the output weights (`_wo`), then the deeper hidden layers ([`deep_arrays`]).
fn network_arrays(m: &ModelFile, s: &Scaling, prefix: &str) -> String {
    let h = &m.layers[0];
    let o = m.layers.last().expect("checked: an output layer");
    let deep = &m.layers[1..m.layers.len() - 1];
    [
        array(&format!("{prefix}_lo"), &s.lo),
        array(&format!("{prefix}_hi"), &s.hi),
        array(&format!("{prefix}_gx"), &s.gx),
        array(&format!("{prefix}_ox"), &s.ox),
        array(&format!("{prefix}_w1c"), &s.w1c),
        array(&format!("{prefix}_b1"), &h.biases),
        array(&format!("{prefix}_wo"), &o.weights[0]),
        deep_arrays(deep, prefix),
    ]
    .concat()
}

/// The hidden layers after the first: their weights (`_wd`), biases (`_bd`) and widths
/// (`_deep_n`; one unused 0 for a network of one hidden layer).
fn deep_arrays(deep: &[Layer], prefix: &str) -> String {
    [
        // Stored by input neuron h, then output neuron g (W_gh at h·n + g): the C loop adds
        // one input's terms to every output at a time (see `_net` in c/mlp.h.in).
        array(
            &format!("{prefix}_wd"),
            &deep
                .iter()
                .flat_map(|l| {
                    let n_prev = l.weights.first().map_or(0, Vec::len);
                    (0..n_prev).flat_map(move |h| l.weights.iter().map(move |row| row[h]))
                })
                .collect::<Vec<f64>>(),
        ),
        array(
            &format!("{prefix}_bd"),
            &deep
                .iter()
                .flat_map(|l| l.biases.iter().copied())
                .collect::<Vec<f64>>(),
        ),
        format!(
            "static const int {prefix}_deep_n[{}] = {{{}}};\n",
            deep.len().max(1),
            if deep.is_empty() {
                "0".to_string()
            } else {
                deep.iter()
                    .map(|l| l.biases.len().to_string())
                    .collect::<Vec<_>>()
                    .join(", ")
            }
        ),
    ]
    .concat()
}

/// The data-support grid's arrays (`@sup_arrays@`): cells per input and row-major strides
/// (unused inputs 1), half the cells per input, and per cell whether it is supported (1/0)
/// and its fallback μ.
fn support_arrays(sup: &SupportSpec, prefix: &str) -> String {
    let k = sup.cells.len();
    let mut n = [1usize; MAX_INPUTS];
    n[..k].copy_from_slice(&sup.cells);
    let mut stride = [1usize; MAX_INPUTS];
    for c in (0..k.saturating_sub(1)).rev() {
        stride[c] = stride[c + 1] * n[c + 1];
    }
    let s: Vec<f64> = (0..sup.len())
        .map(|j| if sup.supported(j) { 1.0 } else { 0.0 })
        .collect();
    let join = |v: &[usize]| {
        v.iter()
            .map(|x| x.to_string())
            .collect::<Vec<_>>()
            .join(", ")
    };
    format!(
        "static const int {prefix}_sup_n[{MAX_INPUTS}] = {{{}}};\nstatic const long {prefix}_sup_stride[{MAX_INPUTS}] = {{{}}};\n",
        join(&n),
        join(&stride)
    ) + &array(&format!("{prefix}_sup_half"), &n.map(|v| v as f64 / 2.0))
        + &array(&format!("{prefix}_sup_s"), &s)
        + &array(&format!("{prefix}_sup_f"), &sup.fallback_mu)
}

/// True for a valid C identifier that does not start with an underscore.
pub fn valid_prefix(p: &str) -> bool {
    let mut ch = p.chars();
    matches!(ch.next(), Some(c) if c.is_ascii_alphabetic())
        && ch.all(|c| c.is_ascii_alphanumeric() || c == '_')
}

fn polach_header(m: &ModelFile, p: &PolachSpec, prefix: &str, source: &str) -> String {
    polach_text(
        p,
        prefix,
        &[
            ("source", comment_text(source)),
            ("fmt", comment_text(&m.format)),
            ("fv", m.version.to_string()),
            ("nt", m.metrics.train_samples.to_string()),
            ("rmse", lit(m.metrics.train_mse.sqrt())),
            ("inputs", inputs_line(m)),
        ],
    )
}

/// `c/polach.h.in` for the law `p` under `prefix`, with the descriptive values `about`
/// (source, fmt, fv, nt, rmse, inputs).
fn polach_text(p: &PolachSpec, prefix: &str, about: &[(&str, String)]) -> String {
    let (has_t, mu0_t, ka_t, ks_t, t_lo, t_hi) = match &p.temperature {
        Some(t) => (
            true,
            t.mu0.clone(),
            t.k_a.clone(),
            t.k_s.clone(),
            t.fitted_range_c[0],
            t.fitted_range_c[1],
        ),
        None => (false, vec![], vec![0.0], vec![0.0], 0.0, 0.0),
    };
    // C has no zero-length arrays: an unused μ0(T) gets one 0 (N_MU0_T stays 0).
    let mu0_arr = if mu0_t.is_empty() {
        vec![0.0]
    } else {
        mu0_t.clone()
    };
    // Without a speed law: one unused 0 coefficient and the range [0, 0] (HAS_SPEED 0).
    let (speed_c, ck, v_lo, v_hi) = match &p.speed {
        Some(s) => (
            s.coefficients.clone(),
            s.form == "curtius_kniffler",
            s.fitted_range_mps[0],
            s.fitted_range_mps[1],
        ),
        None => (vec![0.0], false, 0.0, 0.0),
    };
    let up = prefix.to_uppercase();
    let mut values = about.to_vec();
    values.extend([
        ("pre", prefix.to_string()),
        ("guard", format!("{up}_ADHESION_MODEL_H")),
        ("up", up),
        (
            "tl",
            match (has_t, mu0_t.is_empty()) {
                (false, _) => "",
                (true, true) => " and k_A(T), k_S(T)",
                (true, false) => " and μ0(T), k_A(T), k_S(T)",
            }
            .to_string(),
        ),
        (
            "vl",
            match &p.speed {
                None => String::new(),
                Some(s) => format!(" and μ0's speed law ({})", s.form),
            },
        ),
        ("ver", env!("CARGO_PKG_VERSION").to_string()),
        ("has_t", u8::from(has_t).to_string()),
        ("has_v", u8::from(p.speed.is_some()).to_string()),
        ("ck", u8::from(ck).to_string()),
        ("nsp", speed_c.len().to_string()),
        ("v_lo", lit(v_lo)),
        ("v_hi", lit(v_hi)),
        ("v_c", lit(CURTIUS_KNIFFLER_SPEED_MPS)),
        ("cfix", u8::from(p.creepage_speed_mps.is_some()).to_string()),
        (
            "vcr",
            lit(p.creepage_speed_mps.unwrap_or(p.reference_speed_mps)),
        ),
        ("nmu0", mu0_t.len().to_string()),
        ("nka", ka_t.len().to_string()),
        ("nks", ks_t.len().to_string()),
        ("mu0", lit(p.mu0)),
        ("a", lit(p.a_ratio)),
        ("b", lit(p.b_s_per_m)),
        ("k_a", lit(p.k_a)),
        ("k_s", lit(p.k_s)),
        ("stiff", lit(stiffness(p))),
        ("vref", lit(p.reference_speed_mps)),
        ("vmin", lit(MIN_SPEED_MPS)),
        ("pi", lit(std::f64::consts::PI)),
        ("t_lo", lit(t_lo)),
        ("t_hi", lit(t_hi)),
        (
            "arrays",
            array(&format!("{prefix}_mu0_T"), &mu0_arr)
                + &array(&format!("{prefix}_ka_T"), &ka_t)
                + &array(&format!("{prefix}_ks_T"), &ks_t)
                + &array(&format!("{prefix}_speed_c"), &speed_c),
        ),
    ]);
    fill(POLACH_TEMPLATE, &values)
}

#[cfg(test)]
mod literal_tests {
    use super::lit;

    #[test]
    fn every_double_is_written_as_a_literal_that_reads_back() {
        for x in [
            0.0,
            -0.0,
            1.0,
            -2.5,
            5e-324,
            f64::MIN_POSITIVE,
            f64::MAX,
            -f64::MAX,
            1e22,
            0.1 + 0.2,
        ] {
            let s = lit(x);
            assert!(s.contains('.') || s.contains('e'), "{s}");
            assert_eq!(s.parse::<f64>().unwrap().to_bits(), x.to_bits(), "{s}");
        }
        assert_eq!(lit(f64::INFINITY), "HUGE_VAL");
        assert_eq!(lit(f64::NEG_INFINITY), "(-HUGE_VAL)");
        assert_eq!(lit(f64::NAN), "NAN");
    }
}
