//! Retargets a generated example along its known lattice and writes input and output as OBJ.
//! Run: `cargo run --release -p motif-retarget --example retarget_demo -- shelf 1 1 0 [dense]`.

use motif_core::procedural::generate;
use motif_core::progress::NoProgress;
use motif_retarget::retarget::{RetargetMethod, RetargetOptions, retarget};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let name = args.first().map_or("shelf", String::as_str);
    let step = |i: usize| args.get(i).and_then(|s| s.parse::<i32>().ok()).unwrap_or(0);
    let steps = [step(1), step(2), step(3)];
    let method = if args.get(4).is_some_and(|m| m == "dense") {
        RetargetMethod::Dense
    } else {
        RetargetMethod::Offsets
    };
    let ex = generate(name, 0)?;
    let options = RetargetOptions { method, ..Default::default() };
    let out = retarget(&ex.mesh, &ex.structure.cell_pitch, steps, &options, &NoProgress)?;
    println!("{}", serde_json::to_string_pretty(&out.report)?);
    // The labelling, one z-layer at a time, top row first: k0,k1 per voxel.
    let d = out.report.output_voxels;
    for z in 0..d[2] {
        println!("layer z = {z}:");
        for y in (0..d[1]).rev() {
            let row: Vec<String> = (0..d[0])
                .map(|x| {
                    let k = out.voxel_labels[x + d[0] * (y + d[1] * z)];
                    format!("{},{}", k[0], k[1])
                })
                .collect();
            println!("  {}", row.join("  "));
        }
    }
    let dir = std::env::temp_dir();
    motif_core::io::write_mesh(&dir.join(format!("retarget-{name}-input.obj")), &ex.mesh)?;
    let tag = match method {
        RetargetMethod::Offsets => "offsets",
        RetargetMethod::Dense => "dense",
    };
    motif_core::io::write_mesh(&dir.join(format!("retarget-{name}-{tag}.obj")), &out.mesh)?;
    // One line per output triangle: the step vector of the voxel it was copied into.
    let labels: String = out
        .triangle_voxels
        .iter()
        .map(|&v| {
            let k = out.voxel_labels[v as usize];
            format!("{} {} {}\n", k[0], k[1], k[2])
        })
        .collect();
    std::fs::write(dir.join(format!("retarget-{name}-{tag}.labels")), labels)?;
    Ok(())
}
