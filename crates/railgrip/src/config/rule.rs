//! The rules every option of a pipeline or scene file follows: a [`Key`] per option (name, unit,
//! range, default, meaning) in one table per section, which both drives the checks
//! ([`Checker`]) and renders the docs' option tables ([`markdown_rows`]; a test keeps docs/pipeline.md in
//! step with the tables).

use std::fmt;

use super::ConfigError;

/// The values a key accepts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Range {
    /// A finite number between `lo` and `hi`, each bound inclusive unless open.
    Num {
        lo: f64,
        lo_open: bool,
        hi: f64,
        hi_open: bool,
    },
    /// A whole number in [lo, hi].
    Int { lo: f64, hi: f64 },
    /// One of these strings.
    Choice(&'static [&'static str]),
    /// Checked by the section's code (it depends on other keys); the text documents it.
    Text(&'static str),
}

/// [lo, hi].
pub const fn closed(lo: f64, hi: f64) -> Range {
    Range::Num {
        lo,
        lo_open: false,
        hi,
        hi_open: false,
    }
}

/// (lo, hi].
pub const fn open_lo(lo: f64, hi: f64) -> Range {
    Range::Num {
        lo,
        lo_open: true,
        hi,
        hi_open: false,
    }
}

/// A whole number in [lo, hi].
pub const fn int(lo: f64, hi: f64) -> Range {
    Range::Int { lo, hi }
}

/// What a key is when the file leaves it out.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Default {
    /// This number.
    Num(f64),
    /// Required in a user's file; the embedded UIC-Z1 pipeline's value is quoted in the message.
    Required(f64),
    /// Documented by this text (a default that depends on other keys, a string, a list).
    Text(&'static str),
}

/// One option of a pipeline or scene file.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Key {
    /// Full name, `section.key`.
    pub name: &'static str,
    /// Unit of the value as written in the file ("" for none).
    pub unit: &'static str,
    pub range: Range,
    pub default: Default,
    /// What it means; `[pub]` / `[assumed]` tags name the source of the default.
    pub meaning: &'static str,
}

impl Key {
    /// A numeric key with a default.
    pub const fn num(
        name: &'static str,
        unit: &'static str,
        range: Range,
        default: f64,
        meaning: &'static str,
    ) -> Key {
        Key {
            name,
            unit,
            range,
            default: Default::Num(default),
            meaning,
        }
    }

    pub(crate) fn rule_text(&self) -> String {
        match self.range {
            Range::Num {
                lo,
                lo_open,
                hi,
                hi_open,
            } => {
                let u = if self.unit.is_empty() {
                    String::new()
                } else {
                    format!(" {}", self.unit)
                };
                let mut s = format!(
                    "must be {} {}{u} and {} {}{u}",
                    if lo_open { ">" } else { ">=" },
                    g(lo),
                    if hi_open { "<" } else { "<=" },
                    g(hi)
                );
                if let Default::Num(d) = self.default {
                    s.push_str(&format!(" (default {}{u})", g(d)));
                }
                s
            }
            Range::Int { lo, hi } => {
                let mut s = format!("must be >= {} and <= {}", g(lo), g(hi));
                if let Default::Num(d) = self.default {
                    s.push_str(&format!(" (default {})", g(d)));
                }
                s
            }
            Range::Choice(names) => {
                let names: Vec<String> = names.iter().map(|n| format!("\"{n}\"")).collect();
                let mut s = format!("must be one of {}", names.join(", "));
                if let Default::Text(d) = self.default {
                    s.push_str(&format!(" (default {d})"));
                }
                s
            }
            Range::Text(t) => format!("must be {t}"),
        }
    }

    pub(crate) fn contains(&self, x: f64) -> bool {
        match self.range {
            Range::Num {
                lo,
                lo_open,
                hi,
                hi_open,
            } => {
                x.is_finite()
                    && (if lo_open { x > lo } else { x >= lo })
                    && (if hi_open { x < hi } else { x <= hi })
            }
            Range::Int { lo, hi } => x.is_finite() && x >= lo && x <= hi,
            Range::Choice(_) | Range::Text(_) => true,
        }
    }

    /// The docs table's cell of the range.
    fn range_cell(&self) -> String {
        match self.range {
            Range::Num {
                lo,
                lo_open,
                hi,
                hi_open,
            } => format!(
                "{}{}, {}{}",
                if lo_open { "(" } else { "[" },
                g(lo),
                g(hi),
                if hi_open { ")" } else { "]" }
            ),
            Range::Int { lo, hi } => format!("{}..{}", g(lo), g(hi)),
            Range::Choice(names) => names
                .iter()
                .map(|n| format!("`\"{n}\"`"))
                .collect::<Vec<_>>()
                .join(", "),
            Range::Text(t) => t.to_string(),
        }
    }

    /// The docs table's cell of the default.
    fn default_cell(&self) -> String {
        match self.default {
            Default::Text(t) if matches!(self.range, Range::Choice(_)) => format!("`{t}`"),
            Default::Num(d) => g(d),
            Default::Required(example) => format!("required (UIC-Z1: {})", g(example)),
            Default::Text(t) => t.to_string(),
        }
    }
}

/// Shortest readable form of a number for messages and tables.
pub fn g(x: f64) -> String {
    if x == x.trunc() && x.abs() < 1e6 {
        format!("{}", x as i64)
    } else if x != 0.0 && (x.abs() < 1e-3 || x.abs() >= 1e6) {
        format!("{x:e}")
    } else {
        let s = format!("{x:.4}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    }
}

/// The docs table's rows (`| key | default | unit | range | meaning |`) of a section's keys.
pub fn markdown_rows(keys: &[&Key]) -> String {
    keys.iter()
        .map(|k| {
            format!(
                "| `{}` | {} | {} | {} | {} |\n",
                k.name,
                k.default_cell(),
                if k.unit.is_empty() { "–" } else { k.unit },
                k.range_cell(),
                k.meaning
            )
        })
        .collect()
}

/// Turns raw values into checked ones, naming the file in every error. Shared by pipeline and
/// scene files so both report problems the same way.
pub(crate) struct Checker<'a> {
    pub(crate) file: &'a str,
}

impl Checker<'_> {
    /// The value of numeric key `k`: `v` when given and within range, else its default; an
    /// error naming the key, the value, the range and the default otherwise.
    pub(crate) fn value(&self, k: &Key, v: Option<f64>) -> Result<f64, ConfigError> {
        match (v, k.default) {
            (None, Default::Num(d)) => Ok(d),
            (None, Default::Required(example)) => Err(self.missing(
                k.name,
                format!(
                    "give it in {}, {} (UIC-Z1: {})",
                    k.unit,
                    k.rule_text(),
                    g(example)
                ),
            )),
            (None, Default::Text(t)) => Err(self.missing(k.name, t)),
            (Some(x), _) if !k.contains(x) => Err(self.invalid(k.name, g(x), k.rule_text())),
            (Some(x), _) if matches!(k.range, Range::Int { .. }) && x.fract() != 0.0 => {
                Err(self.invalid(k.name, g(x), "must be a whole number"))
            }
            (Some(x), _) => Ok(x),
        }
    }

    /// The value of numeric key `k` whose default depends on other keys (`default`).
    pub(crate) fn value_or(
        &self,
        k: &Key,
        v: Option<f64>,
        default: f64,
    ) -> Result<f64, ConfigError> {
        match v {
            None => Ok(default),
            Some(_) => self.value(k, v),
        }
    }

    /// The option of choice key `k` named by `v` (`default` when absent).
    pub(crate) fn choice<T: Copy>(
        &self,
        k: &Key,
        v: Option<String>,
        options: &[(&str, T)],
        default: T,
    ) -> Result<T, ConfigError> {
        match v {
            None => Ok(default),
            Some(s) => options
                .iter()
                .find(|(name, _)| *name == s)
                .map(|(_, t)| *t)
                .ok_or_else(|| self.invalid(k.name, format!("\"{s}\""), k.rule_text())),
        }
    }

    pub(crate) fn invalid(
        &self,
        key: &str,
        value: impl fmt::Display,
        rule: impl fmt::Display,
    ) -> ConfigError {
        ConfigError::Invalid {
            file: self.file.to_string(),
            key: key.to_string(),
            value: value.to_string(),
            rule: rule.to_string(),
        }
    }

    pub(crate) fn missing(&self, key: &str, rule: impl fmt::Display) -> ConfigError {
        ConfigError::Missing {
            file: self.file.to_string(),
            key: key.to_string(),
            rule: rule.to_string(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const K: Key = Key::num("s.k", "m", open_lo(0.0, 5.0), 1.5, "a length");

    #[test]
    fn messages_name_key_value_range_and_default() {
        let c = Checker { file: "f.toml" };
        assert_eq!(c.value(&K, None).unwrap(), 1.5);
        assert_eq!(
            c.value(&K, Some(0.0)).unwrap_err().to_string(),
            "f.toml: s.k = 0: must be > 0 m and <= 5 m (default 1.5 m)"
        );
        assert_eq!(
            markdown_rows(&[&K]),
            "| `s.k` | 1.5 | m | (0, 5] | a length |\n"
        );
    }
}
