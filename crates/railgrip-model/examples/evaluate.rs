//! Evaluate a model file the way a simulator does, with nothing but the lean model crate:
//!
//! ```sh
//! cargo run --release -p railgrip-model --example evaluate [MODEL.json]
//! ```
//!
//! Without an argument it loads the golden two-input network of this source tree
//! (`models/golden/synthetic_mlp.json`); give `out/models/mlp.json` after `railgrip run` to see
//! your campaign's model.

use std::path::PathBuf;

use railgrip_model::Model;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = std::env::args_os()
        .nth(1)
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../models/golden/synthetic_mlp.json")
        });
    // Reads and checks the file (format, version, shapes, finite everywhere on its domain).
    let model = Model::load(&path)?;
    println!(
        "{}: {} model, {} inputs ({})",
        path.display(),
        match model.file.kind {
            railgrip_model::ModelKind::Mlp => "network",
            railgrip_model::ModelKind::Polach => "Polach",
        },
        model.n_inputs(),
        model
            .file
            .inputs
            .iter()
            .map(|i| format!("{} [{}]", i.name, i.unit))
            .collect::<Vec<_>>()
            .join(", ")
    );
    // One call per point: μ(Δv, dΔv/dt) at the model's reference speed.
    println!("\n  Δv m/s   μ (dΔv/dt = +1 m/s²)   μ (dΔv/dt = −1 m/s²)");
    for dv in [0.05, 0.2, 0.5, 1.0, 2.0, 4.0] {
        println!(
            "  {dv:>5.2}   {:>20.5}   {:>20.5}",
            model.mu(dv, 1.0),
            model.mu(dv, -1.0)
        );
    }
    // A whole braking run at once: the batch evaluator runs across SIMD lanes and gives the
    // same bits as the single call.
    let n = 10_000;
    let dv: Vec<f64> = (0..n).map(|k| 4.0 * k as f64 / n as f64).collect();
    let ddv: Vec<f64> = (0..n).map(|k| (k as f64 * 0.01).sin()).collect();
    let mut mu = vec![0.0; n];
    let t0 = std::time::Instant::now();
    model.mu_batch(&dv, &ddv, &[], &mut mu);
    let ns = t0.elapsed().as_secs_f64() * 1e9 / n as f64;
    assert!((0..n).all(|k| mu[k] == model.mu(dv[k], ddv[k])));
    println!("\nbatch of {n} points: {ns:.1} ns per μ, identical to the single calls");
    Ok(())
}
