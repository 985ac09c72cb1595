//! Filters against scipy (tests/data/signal/, made by tests/data/signal/make_reference.py),
//! Hampel despiking and the conditioning of a whole run.

use railgrip::signal::filter::{causal_lanes, zero_phase_lanes, LowPass4, PAD};

const FS: f64 = 417.0;

struct Reference {
    columns: Vec<String>,
    data: Vec<Vec<f64>>,
}

impl Reference {
    fn load(case: &str) -> Reference {
        let path = format!(
            "{}/tests/data/signal/{case}.csv",
            env!("CARGO_MANIFEST_DIR")
        );
        let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
        let mut lines = text.lines();
        let columns: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
        let mut data = vec![Vec::new(); columns.len()];
        for line in lines {
            for (c, v) in line.split(',').enumerate() {
                data[c].push(v.parse::<f64>().unwrap());
            }
        }
        Reference { columns, data }
    }
    fn col(&self, name: &str) -> &[f64] {
        let i = self.columns.iter().position(|c| c == name).unwrap();
        &self.data[i]
    }
}

/// Largest |a − b| relative to the reference's largest magnitude.
fn rel_err(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    let scale = b.iter().fold(0.0f64, |m, v| m.max(v.abs())).max(1e-300);
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
        / scale
}

#[test]
fn butterworth_matches_scipy_sosfilt_and_sosfiltfilt() {
    for case in ["step", "chirp", "radar", "short"] {
        let r = Reference::load(case);
        let x = r.col("x");
        for fc in [1.5, 4.0] {
            let f = LowPass4::butterworth(fc, FS).unwrap();
            let causal = f.causal(x);
            let zp = f.zero_phase(x).unwrap();
            let e1 = rel_err(&causal, r.col(&format!("causal_{fc}")));
            let e2 = rel_err(&zp, r.col(&format!("zero_phase_{fc}")));
            eprintln!("{case} fc={fc}: causal {e1:.1e}, zero-phase {e2:.1e}");
            assert!(e1 <= 1e-9, "{case} {fc} causal: {e1:e}");
            assert!(e2 <= 1e-9, "{case} {fc} zero-phase: {e2:e}");
        }
    }
}

#[test]
fn lockstep_lanes_equal_single_channel_runs_bit_for_bit() {
    let r = Reference::load("radar");
    let c = Reference::load("chirp");
    let (x0, x1) = (r.col("x"), c.col("x"));
    let bank = [
        LowPass4::butterworth(1.5, FS).unwrap(),
        LowPass4::butterworth(4.0, FS).unwrap(),
    ];
    let n = x0.len();
    let mut buf = vec![[0.0; 2]; n + 2 * PAD];
    for j in 0..n {
        buf[PAD + j] = [x0[j], x1[j]];
    }
    zero_phase_lanes(&bank, &mut buf).unwrap();
    let a = bank[0].zero_phase(x0).unwrap();
    let b = bank[1].zero_phase(x1).unwrap();
    for j in 0..n {
        assert_eq!(buf[PAD + j], [a[j], b[j]]);
    }
    let mut buf: Vec<[f64; 2]> = (0..n).map(|j| [x0[j], x1[j]]).collect();
    causal_lanes(&bank, &mut buf);
    let a = bank[0].causal(x0);
    for j in 0..n {
        assert_eq!(buf[j][0], a[j]);
    }
}

#[test]
fn causal_filter_delays_a_ramp_by_its_group_delay() {
    // A ramp through a low-pass with unity DC gain lags by exactly the DC group delay once
    // the transient has died out.
    for fc in [1.5, 4.0] {
        let f = LowPass4::butterworth(fc, FS).unwrap();
        let x: Vec<f64> = (0..4000).map(|i| 30.0 - 0.8 * i as f64 / FS).collect();
        let y = f.causal(&x);
        let lag = (y[3999] - x[3999]) / 0.8; // s
        let expect = f.dc_group_delay_s();
        assert!((lag - expect).abs() < 1e-6, "{fc}: {lag} vs {expect}");
        // And the zero-phase filter has none.
        let z = f.zero_phase(&x).unwrap();
        assert!(
            (z[2000] - x[2000]).abs() < 1e-6,
            "{fc}: {}",
            z[2000] - x[2000]
        );
    }
}
