//! Per-instance non-rigid variation: anisotropic scale, a quadratic bend, a twist about the up
//! axis, and part-wise offsets (see [`super::SceneSettings::variation`] for the amplitudes).

use motif_core::TriMesh;
use motif_core::geometry::{Mat4, Point3, transform_point};
use rand::Rng;

use super::elements::{Mount, Template};

/// One instance's variation, drawn once.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Variation {
    /// Scale factors along x, y, z (about the template origin).
    pub scale: [f64; 3],
    /// Bend: z is displaced by `bend · L · (x / L)²`, `L` the template's half-width.
    pub bend: f64,
    /// Twist about y: angle `twist · y / H` radians, `H` the template's height (ground parts).
    pub twist: f64,
    /// Offset of each part (zero for fixed parts).
    pub offsets: Vec<Point3>,
}

impl Variation {
    /// No variation.
    pub fn none(template: &Template) -> Self {
        Variation { scale: [1.0; 3], bend: 0.0, twist: 0.0, offsets: vec![[0.0; 3]; template.parts.len()] }
    }

    /// Draws a variation of amplitude `v` (0 gives [`Variation::none`] without using `rng`).
    pub fn draw(template: &Template, v: f64, rng: &mut impl Rng) -> Self {
        if v <= 0.0 {
            return Self::none(template);
        }
        let mut u = || 2.0 * rng.random::<f64>() - 1.0;
        let scale = [1.0 + v * u(), 1.0 + v * u(), 1.0 + v * u()];
        let bend = 0.3 * v * u();
        let twist = match template.mount {
            Mount::Ground => v * u(),
            Mount::Wall => 0.0,
        };
        let reach = 0.1 * v * template.bounds().diagonal();
        let offsets = template
            .parts
            .iter()
            .map(|p| if p.movable { [reach * u(), reach * u(), reach * u()] } else { [0.0; 3] })
            .collect();
        Variation { scale, bend, twist, offsets }
    }

    /// The varied template, placed by `world_from_local`, as one mesh (parts concatenated).
    pub fn apply(&self, template: &Template, world_from_local: &Mat4) -> TriMesh {
        let b = template.bounds();
        let half = b.min[0].abs().max(b.max[0].abs()).max(1e-9);
        let height = b.max[1].abs().max(1e-9);
        let mut out = TriMesh::default();
        for (part, off) in template.parts.iter().zip(&self.offsets) {
            let mut m = part.mesh.clone();
            for p in &mut m.positions {
                let q = [
                    (p[0] + off[0]) * self.scale[0],
                    (p[1] + off[1]) * self.scale[1],
                    (p[2] + off[2]) * self.scale[2],
                ];
                let x = q[0] / half;
                let q = [q[0], q[1], q[2] + self.bend * half * x * x];
                let (s, c) = (self.twist * q[1] / height).sin_cos();
                let q = [c * q[0] + s * q[2], q[1], -s * q[0] + c * q[2]];
                *p = transform_point(world_from_local, q);
            }
            out.append(&m);
        }
        out
    }

    /// The wall opening of the varied template (scaled; the bend and offsets leave it alone), in
    /// the template's frame.
    pub fn opening(&self, template: &Template) -> Option<[f64; 4]> {
        template
            .opening
            .map(|o| [o[0] * self.scale[0], o[1] * self.scale[1], o[2] * self.scale[0], o[3] * self.scale[1]])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use motif_core::geometry::IDENTITY4;
    use rand::SeedableRng;

    #[test]
    fn no_variation_is_the_identity_and_variation_stays_in_bounds() {
        let t = super::super::elements::car().unwrap();
        let plain = Variation::none(&t).apply(&t, &IDENTITY4);
        let mut flat = TriMesh::default();
        for p in &t.parts {
            flat.append(&p.mesh);
        }
        assert_eq!(plain, flat);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let v = Variation::draw(&t, 0.15, &mut rng);
        assert!(v.scale.iter().all(|s| (0.85..=1.15).contains(s)));
        assert!(v.twist.abs() <= 0.15 && v.bend.abs() <= 0.045);
        let varied = v.apply(&t, &IDENTITY4);
        assert_eq!(varied.triangles, flat.triangles);
        assert_ne!(varied.positions, flat.positions);
    }
}
