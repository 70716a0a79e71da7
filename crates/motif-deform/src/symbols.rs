//! Which annotated regions a point lies in, as bit sets over the annotation's regions ("symbols").
//!
//! Two sets are used:
//! - `has(p)`: every region containing `p` (a group's region, or any instance of an instance
//!   set). A sample's orbit closure applies the maps of exactly these regions (thesis 3.4).
//! - `required(p)`: the group regions containing `p`, plus for each instance set the *home*
//!   instance of `p`: among the instances containing it, the one in whose template coordinates
//!   `T_b⁻¹ p` is lexicographically smallest (ties: lowest index). The per-region coverage pass of
//!   symmetric sampling adds an orbit where a candidate `p` has no sample `l` within `r` with
//!   `required(p) ⊆ has(l)`, so every region is sampled on its own (the lifting's equivariant
//!   support, `lift.rs`, then finds samples of the right regions near every vertex).

use std::collections::HashMap;

use motif_core::TriMesh;
use motif_core::geometry::Point3;

use crate::annotation::{NearestVertex, ResolvedAnnotation, ResolvedKind, apply};
use crate::error::Result;

/// A bit set over the annotation's regions.
pub(crate) type Bits = Vec<u64>;

/// `a ⊆ b`.
#[inline]
pub(crate) fn subset(a: &[u64], b: &[u64]) -> bool {
    a.iter().zip(b).all(|(x, y)| x & !y == 0)
}

#[inline]
pub(crate) fn set_bit(b: &mut [u64], i: usize) {
    b[i / 64] |= 1 << (i % 64);
}

#[inline]
pub(crate) fn get_bit(b: &[u64], i: usize) -> bool {
    b[i / 64] >> (i % 64) & 1 == 1
}

/// Region tests for points and vertices.
pub(crate) struct Symbols<'a> {
    pub(crate) resolved: &'a ResolvedAnnotation,
    nearest: NearestVertex,
    pub(crate) words: usize,
}

impl<'a> Symbols<'a> {
    pub(crate) fn new(mesh: &TriMesh, resolved: &'a ResolvedAnnotation) -> Result<Self> {
        Ok(Symbols {
            resolved,
            nearest: NearestVertex::new(mesh, resolved)?,
            words: resolved.num_symbols.div_ceil(64),
        })
    }

    pub(crate) fn empty(&self) -> Bits {
        vec![0; self.words]
    }

    /// Every region containing the point `p`.
    pub(crate) fn point_has(&self, p: Point3) -> Bits {
        let nearest = self.nearest.get(p);
        let mut b = self.empty();
        for s in &self.resolved.symmetries {
            match &s.kind {
                ResolvedKind::Group { region, .. } => {
                    if region.test.contains_point(p, nearest) {
                        set_bit(&mut b, region.symbol);
                    }
                }
                ResolvedKind::Instances { instances, .. } => {
                    for r in instances {
                        if r.test.contains_point(p, nearest) {
                            set_bit(&mut b, r.symbol);
                        }
                    }
                }
            }
        }
        b
    }

    /// The regions whose samples may influence the point `p` (see the module docs).
    pub(crate) fn point_required(&self, p: Point3) -> Bits {
        let nearest = self.nearest.get(p);
        let inside = |t: &crate::annotation::RegionTest| t.contains_point(p, nearest);
        let tol = self.resolved.margin;
        let mut b = self.empty();
        for s in &self.resolved.symmetries {
            match &s.kind {
                ResolvedKind::Group { region, .. } => {
                    if inside(&region.test) {
                        set_bit(&mut b, region.symbol);
                    }
                }
                ResolvedKind::Instances { instances, inverses, .. } => {
                    let mut home: Option<(usize, Point3)> = None;
                    for (i, r) in instances.iter().enumerate() {
                        if !inside(&r.test) {
                            continue;
                        }
                        let y = apply(&inverses[i], p);
                        let better = match &home {
                            None => true,
                            Some((_, best)) => lexicographically_less(y, *best, tol),
                        };
                        if better {
                            home = Some((i, y));
                        }
                    }
                    if let Some((i, _)) = home {
                        set_bit(&mut b, instances[i].symbol);
                    }
                }
            }
        }
        b
    }
}

/// `a < b` lexicographically, coordinates within `tol` counting as equal.
fn lexicographically_less(a: Point3, b: Point3, tol: f64) -> bool {
    for k in 0..3 {
        if a[k] < b[k] - tol {
            return true;
        }
        if a[k] > b[k] + tol {
            return false;
        }
    }
    false
}

/// Interns bit sets: equal sets get the same id.
#[derive(Debug, Default, Clone)]
pub(crate) struct Interner {
    ids: HashMap<Bits, u32>,
    pub(crate) sets: Vec<Bits>,
}

impl Interner {
    pub(crate) fn id(&mut self, b: Bits) -> u32 {
        if let Some(&i) = self.ids.get(&b) {
            return i;
        }
        let i = self.sets.len() as u32;
        self.sets.push(b.clone());
        self.ids.insert(b, i);
        i
    }
}
