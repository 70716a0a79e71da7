//! SHOT's local reference frame (Tombari, Salti, Di Stefano 2010, §4), with the sign
//! disambiguation PCL's `SHOTLocalReferenceFrameEstimation` uses.

use nalgebra::{Matrix3, SymmetricEigen};

use super::Offset;
use crate::geometry::{Point3, cross, dot};

/// Half-width of the window of neighbours around the median distance that decides an axis's sign
/// when the neighbours split exactly evenly (PCL looks at 5 neighbours).
const TIE_HALF_WINDOW: usize = 2;

/// The frame `[x, y, z]` (unit, right-handed) of a keypoint from its neighbours' offsets, or `None`
/// when the covariance is not finite (e.g. every neighbour lies on the sphere of radius `radius`,
/// so every weight is zero).
///
/// `M = Σ (R − dᵢ) δᵢ δᵢᵀ / Σ (R − dᵢ)` over the offsets `δᵢ` (lengths `dᵢ`); `x` is the
/// eigenvector of its largest eigenvalue, `z` of its smallest. Each is signed so that at least
/// half of the offsets have a non-negative component along it; on an exact tie, the sign that the
/// majority of the 5 offsets around the median distance (sorted by distance, then index) have a
/// positive component along. `y = z × x`. May reorder `offsets`.
pub(crate) fn shot_lrf(offsets: &mut [Offset], radius: f64) -> Option<[Point3; 3]> {
    let mut m = [[0.0_f64; 3]; 3];
    let mut weight_sum = 0.0;
    for o in offsets.iter() {
        let w = radius - o.distance;
        let d = o.delta;
        for r in 0..3 {
            for c in 0..=r {
                m[r][c] += w * d[r] * d[c];
            }
        }
        weight_sum += w;
    }
    let mut cov = Matrix3::<f64>::zeros();
    for r in 0..3 {
        for c in 0..=r {
            let v = m[r][c] / weight_sum;
            cov[(r, c)] = v;
            cov[(c, r)] = v;
        }
    }
    if !cov.iter().all(|v| v.is_finite()) {
        return None;
    }
    // Bounded iterations: a 3×3 converges in a handful; never loop forever on odd input.
    let eigen = SymmetricEigen::try_new(cov, f64::EPSILON, 1000)?;
    if !eigen.eigenvalues.iter().all(|v| v.is_finite()) {
        return None;
    }
    let values = eigen.eigenvalues;
    let largest = (0..3).max_by(|&a, &b| values[a].total_cmp(&values[b])).unwrap_or(0);
    let smallest =
        (0..3).filter(|&i| i != largest).min_by(|&a, &b| values[a].total_cmp(&values[b])).unwrap_or(2);
    let column = |i: usize| -> Point3 {
        let c = eigen.eigenvectors.column(i);
        [c[0], c[1], c[2]]
    };
    let mut x = column(largest);
    let mut z = column(smallest);

    let n = offsets.len();
    let mut x_nonneg = 0usize;
    let mut z_nonneg = 0usize;
    for o in offsets.iter() {
        x_nonneg += usize::from(dot(o.delta, x) >= 0.0);
        z_nonneg += usize::from(dot(o.delta, z) >= 0.0);
    }
    let mut sorted = false;
    for (axis, nonneg) in [(&mut x, x_nonneg), (&mut z, z_nonneg)] {
        let flip = if 2 * nonneg == n {
            if !sorted {
                offsets
                    .sort_unstable_by(|a, b| a.distance.total_cmp(&b.distance).then(a.index.cmp(&b.index)));
                sorted = true;
            }
            let median = n / 2;
            let lo = median.saturating_sub(TIE_HALF_WINDOW);
            let hi = (median + TIE_HALF_WINDOW).min(n - 1);
            let positive = offsets[lo..=hi].iter().filter(|o| dot(o.delta, *axis) > 0.0).count();
            positive <= TIE_HALF_WINDOW
        } else {
            2 * nonneg < n
        };
        if flip {
            *axis = axis.map(|c| -c);
        }
    }
    let y = cross(z, x);
    Some([x, y, z])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{norm, sub};

    fn offsets(points: &[Point3], centre: Point3) -> Vec<Offset> {
        points
            .iter()
            .enumerate()
            .map(|(index, &q)| {
                let delta = sub(q, centre);
                Offset { index, delta, distance: norm(delta) }
            })
            .filter(|o| o.distance > 0.0)
            .collect()
    }

    #[test]
    fn frame_of_a_tilted_elongated_patch() {
        // Points on the plane z = 0, spread more along x, lifted on one side so the majority of
        // offsets lies at z ≥ 0; more points at x > 0 than x < 0.
        let mut pts = Vec::new();
        for i in -5..=8 {
            for j in -2..=2 {
                pts.push([i as f64 * 0.1, j as f64 * 0.05, if i > 0 { 0.001 } else { 0.0 }]);
            }
        }
        let mut offs = offsets(&pts, [0.0; 3]);
        let [x, y, z] = shot_lrf(&mut offs, 2.0).unwrap();
        assert!(x[0] > 0.99, "{x:?}");
        assert!(z[2] > 0.99, "{z:?}");
        assert!((dot(cross(x, y), z) - 1.0).abs() < 1e-9);
    }

    #[test]
    fn zero_weights_give_no_frame() {
        let pts = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0]];
        let mut offs = offsets(&pts, [0.0; 3]);
        assert!(shot_lrf(&mut offs, 1.0).is_none());
    }
}
