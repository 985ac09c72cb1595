//! Simulate a braking scene and look at its truth — what `railgrip simulate` does:
//!
//! ```sh
//! cargo run --release --example simulate [SCENE.toml] [OUT]
//! ```
//!
//! Without arguments: the bundled scene `pipelines/scenes/soap_120kmh_p20.toml`, written to
//! `out-example-sim/` as CSV + metadata sidecar and the truth table. A scene pays only for the
//! effects it lists (docs/simulator.md).

use std::path::PathBuf;

use railgrip::sim::{self, OutputFormat, Scene};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args_os().skip(1).map(PathBuf::from);
    let scene_path = args.next().unwrap_or_else(|| {
        PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("../../pipelines/scenes/soap_120kmh_p20.toml")
    });
    let out = args.next().unwrap_or_else(|| "out-example-sim".into());
    let scene = Scene::load(&scene_path)?; // checked: every key in range, effects known
    let t0 = std::time::Instant::now();
    let run = sim::simulate(&scene, None)?; // the scene's own seed
    let wall = t0.elapsed().as_secs_f64();
    println!(
        "{}: {:.1} s braked in {} steps, {:.0}× real time; effects: {}",
        scene.name,
        run.duration_s,
        run.steps,
        run.duration_s / wall,
        scene.effects.names().join(", ")
    );
    // The true adhesion the wheels saw, as (Δv, dΔv/dt, v, μ) samples per axle.
    let truth = run.truth.samples(scene.run.ambient_temperature_c);
    let peak = truth.iter().map(|s| s.mu).fold(0.0, f64::max);
    println!("truth: {} samples, peak μ {peak:.4}", truth.len());
    for p in run.write(out.as_ref(), &scene.name, OutputFormat::Csv)? {
        println!("wrote {}", p.display());
    }
    Ok(())
}
