//! The brakes of one axle: the demanded cylinder pressure (a piecewise linear profile), the
//! wheel-slide protection that may override it, and the first-order cylinder that follows the
//! command.
//!
//! WSP per axle (docs/simulator.md, effect `wsp`; thresholds railgrip's [assumed] values):
//! Apply → Detect when the slip exceeds max(dump_slip_mps, dump_slip_ratio·v) or the wheel
//! decelerates faster than the vehicle by more than decel_limit_mps2; Detect → Dump after the
//! reaction delay; Dump → Hold (keeping the pressure reached) once the slip falls below the dump
//! threshold and is recovering; Hold → Apply when the slip is below reapply_slip_mps or after
//! hold_max_s, Hold → Dump when the slip grows past the threshold again.

use super::scene::WspSection;

/// Linear interpolation of the brake demand (t s, p bar), held after the last point; `cursor`
/// advances with t.
#[inline(always)]
pub(super) fn demand_at(points: &[(f64, f64)], t: f64, cursor: &mut usize) -> f64 {
    while *cursor + 1 < points.len() && points[*cursor + 1].0 <= t {
        *cursor += 1;
    }
    let (t0, p0) = points[*cursor];
    if t <= t0 || *cursor + 1 == points.len() {
        return if t < points[0].0 { points[0].1 } else { p0 };
    }
    let (t1, p1) = points[*cursor + 1];
    p0 + (p1 - p0) * (t - t0) / (t1 - t0)
}

/// Wheel-slide protection state of one axle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
enum WspState {
    /// Brake as demanded.
    #[default]
    Apply,
    /// A slide was detected; the valve vents after the reaction delay.
    Detect,
    /// Venting the cylinder.
    Dump,
    /// Keeping the cylinder pressure, at most `hold_max_s`.
    Hold,
}

/// The WSP controller of one axle.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Wsp {
    state: WspState,
    /// Time in the current state, s.
    timer: f64,
    /// Pressure kept while holding, bar.
    hold_bar: f64,
}

/// What the controller sees of one axle at the start of a step.
pub(super) struct AxleReading {
    /// Vehicle speed v, m/s.
    pub v_mps: f64,
    /// Slip Δv = v − rω, m/s.
    pub slip_mps: f64,
    /// Slip rate dΔv/dt of the last step, m/s².
    pub slip_rate_mps2: f64,
    /// Wheel deceleration beyond the vehicle's, −r ω̇ − d, m/s².
    pub decel_excess_mps2: f64,
    /// Cylinder pressure, bar.
    pub p_bar: f64,
}

impl Wsp {
    /// The cylinder command (bar) for `demand_bar` after a step of `h` s in which the axle
    /// reads `x`.
    #[inline(always)]
    pub(super) fn command(
        &mut self,
        w: &WspSection,
        h: f64,
        x: &AxleReading,
        demand_bar: f64,
    ) -> f64 {
        let dump_at = w.dump_slip_mps.max(w.dump_slip_ratio * x.v_mps);
        let sliding = x.slip_mps > dump_at || x.decel_excess_mps2 > w.decel_limit_mps2;
        self.timer += h;
        let next = match self.state {
            WspState::Apply if sliding => WspState::Detect,
            WspState::Detect if self.timer >= w.reaction_delay_s => WspState::Dump,
            WspState::Dump if x.slip_mps < dump_at && x.slip_rate_mps2 < 0.0 => {
                self.hold_bar = x.p_bar;
                WspState::Hold
            }
            WspState::Hold if x.slip_mps < w.reapply_slip_mps || self.timer >= w.hold_max_s => {
                WspState::Apply
            }
            WspState::Hold if x.slip_mps > dump_at && x.slip_rate_mps2 > 0.0 => WspState::Dump,
            s => s,
        };
        if next != self.state {
            self.timer = 0.0;
            self.state = next;
        }
        match self.state {
            WspState::Apply | WspState::Detect => demand_bar,
            WspState::Dump => 0.0,
            WspState::Hold => self.hold_bar.min(demand_bar),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn demand_is_interpolated_and_held() {
        let pts = [(1.0, 0.0), (2.0, 4.0)];
        let mut c = 0;
        assert_eq!(demand_at(&pts, 0.0, &mut c), 0.0);
        assert_eq!(demand_at(&pts, 1.5, &mut c), 2.0);
        assert_eq!(demand_at(&pts, 9.0, &mut c), 4.0);
    }

    #[test]
    fn a_slide_dumps_after_the_delay_holds_and_reapplies() {
        let w = WspSection {
            dump_slip_mps: 1.0,
            reapply_slip_mps: 0.3,
            decel_limit_mps2: 4.0,
            dump_slip_ratio: 0.1,
            reaction_delay_s: 0.01,
            hold_max_s: 0.4,
        };
        let mut c = Wsp::default();
        let read = |slip: f64, rate: f64| AxleReading {
            v_mps: 5.0,
            slip_mps: slip,
            slip_rate_mps2: rate,
            decel_excess_mps2: 0.0,
            p_bar: 3.0,
        };
        assert_eq!(c.command(&w, 0.005, &read(0.5, 1.0), 3.8), 3.8);
        assert_eq!(c.command(&w, 0.005, &read(1.5, 1.0), 3.8), 3.8); // detect
        assert_eq!(c.command(&w, 0.005, &read(1.5, 1.0), 3.8), 3.8);
        assert_eq!(c.command(&w, 0.006, &read(1.5, 1.0), 3.8), 0.0); // dump after 10 ms
        assert_eq!(c.command(&w, 0.005, &read(0.8, -1.0), 3.8), 3.0); // hold at 3 bar
        assert_eq!(c.command(&w, 0.005, &read(0.2, -1.0), 3.8), 3.8); // re-apply
    }
}
