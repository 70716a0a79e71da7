//! A fence: `n` posts at a fixed pitch along x and horizontal rails fixed to the posts' front faces,
//! one rail segment per bay and rail height running from post centre to post centre. A 1-D
//! translational lattice. The fence stands on `y = 0`; rails face +z.

use serde::{Deserialize, Serialize};

use crate::procedural::Example;
use crate::procedural::primitives::{Annotator, Assembly, box_part, check_positive, check_resolution};
use crate::procedural::structure::{Structure, SymmetryAnnotation, translation};
use crate::{Error, Result};

/// Options of [`fence`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct FenceOptions {
    /// Number of posts `n` (there are `n − 1` bays); 2 to 10000, default 8.
    pub posts: usize,
    /// Distance between neighbouring posts (the lattice pitch), metres; default 1.5.
    pub pitch: f64,
    /// Post size `[width (x), height (y), depth (z)]`, metres; default `[0.1, 1.2, 0.1]`.
    pub post_size: [f64; 3],
    /// Heights of the rails' centres above the ground, metres; default `[0.35, 0.9]`.
    pub rail_heights: Vec<f64>,
    /// Rail cross-section `[height (y), depth (z)]`, metres; default `[0.1, 0.03]`.
    pub rail_size: [f64; 2],
    /// Subdivision multiplier of the whole tessellation; default 1.
    pub resolution: usize,
}

impl Default for FenceOptions {
    fn default() -> Self {
        FenceOptions {
            posts: 8,
            pitch: 1.5,
            post_size: [0.1, 1.2, 0.1],
            rail_heights: vec![0.35, 0.9],
            rail_size: [0.1, 0.03],
            resolution: 1,
        }
    }
}

/// Generates the fence. Structure: instance-set symmetries `posts` and `bays` (translations by
/// multiples of the pitch), the matching instance classes `post` and `bay`, `cell_pitch =
/// [(pitch, 0, 0)]`, `cells = [n, 1, 1]`.
pub fn fence(o: &FenceOptions) -> Result<Example> {
    let res = check_resolution(o.resolution)?;
    let n = o.posts;
    if !(2..=10_000).contains(&n) {
        return Err(Error::InvalidOption {
            name: "posts",
            message: format!("need 2 to 10000 posts, got {n}"),
        });
    }
    check_positive("pitch", o.pitch)?;
    for v in o.post_size.iter().chain(&o.rail_size) {
        check_positive("post_size/rail_size", *v)?;
    }
    let [pw, ph, pd] = o.post_size;
    let [rh, rd] = o.rail_size;
    if pw >= o.pitch {
        return Err(Error::InvalidOption {
            name: "post_size",
            message: "posts wider than the pitch overlap".into(),
        });
    }
    if o.rail_heights.iter().any(|&y| !(y - 0.5 * rh > 0.0 && y + 0.5 * rh < ph)) {
        return Err(Error::InvalidOption {
            name: "rail_heights",
            message: format!("every rail must lie between the ground and the post top ({ph} m)"),
        });
    }
    let mut asm = Assembly::default();
    let mut posts = Vec::new();
    let mut post_t = Vec::new();
    for i in 0..n {
        let x = i as f64 * o.pitch;
        let p = box_part([x - 0.5 * pw, 0.0, -0.5 * pd], [x + 0.5 * pw, ph, 0.5 * pd], [res, 4 * res, res]);
        posts.push(vec![asm.add(format!("post {i}"), &p)]);
        post_t.push(translation([x, 0.0, 0.0]));
    }
    let mut bays = Vec::new();
    let mut bay_t = Vec::new();
    for i in 0..n - 1 {
        let x = i as f64 * o.pitch;
        let mut parts = Vec::new();
        for (r, &y) in o.rail_heights.iter().enumerate() {
            let rail = box_part(
                [x, y - 0.5 * rh, 0.5 * pd],
                [x + o.pitch, y + 0.5 * rh, 0.5 * pd + rd],
                [4 * res, res, res],
            );
            parts.push(asm.add(format!("rail {i}.{r}"), &rail));
        }
        bays.push(parts);
        bay_t.push(translation([x, 0.0, 0.0]));
    }
    let ann = Annotator::new(&asm)?;
    let mut symmetries = vec![ann.instances("posts", &posts, &post_t)];
    let mut instances = vec![ann.class("post", &posts, &post_t)];
    if n > 2 && !o.rail_heights.is_empty() {
        symmetries.push(ann.instances("bays", &bays, &bay_t));
    }
    if !o.rail_heights.is_empty() {
        instances.push(ann.class("bay", &bays, &bay_t));
    }
    let structure = Structure {
        symmetry: SymmetryAnnotation { symmetries, ..Default::default() },
        cell_pitch: vec![[o.pitch, 0.0, 0.0]],
        cells: Some([n, 1, 1]),
        instances,
    };
    Ok(Example { name: "fence".into(), mesh: asm.mesh, structure })
}
