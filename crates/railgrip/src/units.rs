//! Physical units accepted in input logs and their conversion to railgrip's canonical units.
//!
//! Canonical units (architecture.md): time s, speed m/s, angular speed rad/s, pressure bar
//! (gauge). Every conversion here is a pure scale factor: the offset-free units a braking
//! logger writes (gauge pressure in kPa, Pa, MPa is still gauge).

use std::fmt;

/// What a signal measures; decides which units are allowed for it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Quantity {
    Time,
    Speed,
    AngularSpeed,
    Pressure,
}

impl Quantity {
    /// The canonical unit railgrip converts this quantity to.
    pub fn canonical(self) -> Unit {
        match self {
            Quantity::Time => Unit::Second,
            Quantity::Speed => Unit::MetrePerSecond,
            Quantity::AngularSpeed => Unit::RadianPerSecond,
            Quantity::Pressure => Unit::Bar,
        }
    }

    /// Units accepted for this quantity, as spelled in configs (first spelling of each).
    pub fn accepted(self) -> &'static [&'static str] {
        match self {
            Quantity::Time => &["s", "ms", "us", "ns"],
            Quantity::Speed => &["m/s", "km/h"],
            Quantity::AngularSpeed => &["rad/s", "rpm", "rev/s"],
            Quantity::Pressure => &["bar", "kPa", "Pa", "MPa"],
        }
    }
}

impl fmt::Display for Quantity {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Quantity::Time => "time",
            Quantity::Speed => "speed",
            Quantity::AngularSpeed => "angular speed",
            Quantity::Pressure => "pressure",
        })
    }
}

/// A unit an input column or MCAP field may be written in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Unit {
    Second,
    Millisecond,
    Microsecond,
    Nanosecond,
    MetrePerSecond,
    KilometrePerHour,
    RadianPerSecond,
    RevolutionPerMinute,
    RevolutionPerSecond,
    Bar,
    Kilopascal,
    Pascal,
    Megapascal,
}

impl Unit {
    /// Parses a unit for `quantity`. Spellings are matched exactly, with a few common aliases
    /// (`mps`, `kmh`, `kph`, `µs`, `1/min`, `rps`, `kpa`, `mpa`).
    pub fn parse(quantity: Quantity, text: &str) -> Option<Unit> {
        let u = match (quantity, text.trim()) {
            (Quantity::Time, "s") => Unit::Second,
            (Quantity::Time, "ms") => Unit::Millisecond,
            (Quantity::Time, "us" | "µs" | "μs") => Unit::Microsecond,
            (Quantity::Time, "ns") => Unit::Nanosecond,
            (Quantity::Speed, "m/s" | "mps") => Unit::MetrePerSecond,
            (Quantity::Speed, "km/h" | "kmh" | "kph") => Unit::KilometrePerHour,
            (Quantity::AngularSpeed, "rad/s") => Unit::RadianPerSecond,
            (Quantity::AngularSpeed, "rpm" | "1/min") => Unit::RevolutionPerMinute,
            (Quantity::AngularSpeed, "rev/s" | "rps") => Unit::RevolutionPerSecond,
            (Quantity::Pressure, "bar") => Unit::Bar,
            (Quantity::Pressure, "kPa" | "kpa") => Unit::Kilopascal,
            (Quantity::Pressure, "Pa" | "pa") => Unit::Pascal,
            (Quantity::Pressure, "MPa" | "mpa") => Unit::Megapascal,
            _ => return None,
        };
        Some(u)
    }

    /// Multiply a value in this unit by this factor to get the canonical unit.
    pub fn to_canonical_factor(self) -> f64 {
        match self {
            Unit::Second => 1.0,
            Unit::Millisecond => 1e-3,
            Unit::Microsecond => 1e-6,
            Unit::Nanosecond => 1e-9,
            Unit::MetrePerSecond => 1.0,
            Unit::KilometrePerHour => 1.0 / 3.6,
            Unit::RadianPerSecond => 1.0,
            Unit::RevolutionPerMinute => std::f64::consts::TAU / 60.0,
            Unit::RevolutionPerSecond => std::f64::consts::TAU,
            Unit::Bar => 1.0,
            Unit::Kilopascal => 1e-2,
            Unit::Pascal => 1e-5,
            Unit::Megapascal => 10.0,
        }
    }

    pub fn symbol(self) -> &'static str {
        match self {
            Unit::Second => "s",
            Unit::Millisecond => "ms",
            Unit::Microsecond => "us",
            Unit::Nanosecond => "ns",
            Unit::MetrePerSecond => "m/s",
            Unit::KilometrePerHour => "km/h",
            Unit::RadianPerSecond => "rad/s",
            Unit::RevolutionPerMinute => "rpm",
            Unit::RevolutionPerSecond => "rev/s",
            Unit::Bar => "bar",
            Unit::Kilopascal => "kPa",
            Unit::Pascal => "Pa",
            Unit::Megapascal => "MPa",
        }
    }
}

impl fmt::Display for Unit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.symbol())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_accepted_spelling_parses_and_round_trips_its_symbol() {
        for q in [
            Quantity::Time,
            Quantity::Speed,
            Quantity::AngularSpeed,
            Quantity::Pressure,
        ] {
            for s in q.accepted() {
                let u = Unit::parse(q, s).unwrap_or_else(|| panic!("{s} should parse"));
                assert_eq!(u.symbol(), *s);
            }
            assert_eq!(q.canonical().to_canonical_factor(), 1.0);
        }
    }

    #[test]
    fn units_do_not_cross_quantities() {
        assert_eq!(Unit::parse(Quantity::Speed, "rpm"), None);
        assert_eq!(Unit::parse(Quantity::Pressure, "m/s"), None);
        assert_eq!(Unit::parse(Quantity::Time, "bar"), None);
    }

    #[test]
    fn conversion_factors_match_definitions() {
        let c = |q, s| Unit::parse(q, s).unwrap().to_canonical_factor();
        assert!((120.0 * c(Quantity::Speed, "km/h") - 33.333_333_333_333_336).abs() < 1e-12);
        assert!((60.0 * c(Quantity::AngularSpeed, "rpm") - std::f64::consts::TAU).abs() < 1e-12);
        assert!((c(Quantity::AngularSpeed, "rev/s") - std::f64::consts::TAU).abs() < 1e-15);
        assert!((380.0 * c(Quantity::Pressure, "kPa") - 3.8).abs() < 1e-12);
        assert!((3.8e5 * c(Quantity::Pressure, "Pa") - 3.8).abs() < 1e-12);
        assert!((0.38 * c(Quantity::Pressure, "MPa") - 3.8).abs() < 1e-12);
        assert!((2400.0 * c(Quantity::Time, "us") - 2.4e-3).abs() < 1e-15);
    }
}
