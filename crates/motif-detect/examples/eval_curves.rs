//! Evaluates two generated scenes (a row of "windows" with one missed, one split class and one
//! spurious class) and draws the mean PR and stress curves.
//!
//! `cargo run -p motif-detect --example eval_curves -- OUT.png`

use motif_detect::{DetectedClass, DetectedInstance, DetectionResult, EvalOptions, evaluate_many};

fn class(xs: &[f64], shift: f64) -> DetectedClass {
    DetectedClass::new(
        xs.iter()
            .map(|&x| DetectedInstance::from_box([x + shift, 0.0, 0.0], [x + shift + 1.0, 1.0, 1.0]))
            .collect(),
    )
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::env::args().nth(1).unwrap_or_else(|| "eval_curves.png".into());
    let windows: Vec<f64> = (0..8).map(|k| 2.0 * k as f64).collect();
    let gt =
        DetectionResult { scene: "a".into(), classes: vec![class(&windows, 0.0), class(&[50.0, 52.0], 0.0)] };
    // Windows found with a growing offset (overlap falls along the row), one missed; the other
    // class split in two; one spurious class.
    let det = DetectionResult {
        scene: "a".into(),
        classes: vec![
            class(&windows[..4], 0.6),
            class(&windows[4..7], 0.8),
            class(&[50.0], 0.1),
            class(&[52.0], 0.0),
            class(&[80.0, 82.0, 84.0], 0.0),
        ],
    };
    let summary = evaluate_many([(&det, &gt), (&gt, &gt)], &EvalOptions::default())?;
    println!("{}", serde_json::to_string_pretty(&summary.scenes[0])?);
    motif_detect::plot_pr_and_stress(&summary, std::path::Path::new(&out))?;
    println!("wrote {out}");
    Ok(())
}
