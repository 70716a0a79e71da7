//! Grid MRF problems in the shared `mrf_grid_v1` JSON format: loading, validation, solving by
//! alpha-expansion, and a generator of benchmark instances.
//!
//! The format (`shared/formats/mrf.md`) describes a multi-label MRF on an `nx × ny × nz` voxel
//! grid, the shape of the thesis's retargeting space Ω (section 4.2.2), so that Motif's solver can
//! be compared with GCO and PyMaxflow on identical problems:
//! - site index `p = (x·ny + y)·nz + z` (C order, z fastest);
//! - `unary[p·L + l]` = D_p(l), integers; `invalid_cost` marks forbidden labels (a large finite
//!   cost, treated like any other cost);
//! - `pairwise` an L×L integer matrix V, the same for every neighbour pair, scaled by
//!   `edge_weight`;
//! - neighbours: 6-connectivity (offsets (1,0,0), (0,1,0), (0,0,1)) or 26-connectivity (the 13
//!   lexicographically positive offsets in {−1,0,1}³), each unordered pair once, ordered (lower
//!   site index, higher site index) when V is read;
//! - E = Σ_p `unary[p·L + x_p]` + edge_weight · Σ_{pairs {p,q}} `V[x_p][x_q]`.
//!
//! Energies are exact 64-bit integers; loading rejects problems whose energy could overflow.

use std::path::Path;
use std::time::Instant;

use rand::{Rng, SeedableRng};
use serde::{Deserialize, Serialize};
use serde_json::Value;

use crate::alpha_expansion::{
    AlphaExpansion, AlphaExpansionOptions, AlphaExpansionResult, MrfEnergy, Termination,
};
use crate::error::{Error, Result};
use crate::maxflow::Capacity;

/// The `format` value of a grid MRF problem.
pub const FORMAT: &str = "mrf_grid_v1";

/// The initial-labelling rule of the shipped files: per-site argmin of the unary, lowest label on
/// ties.
pub const ARGMIN_RULE: &str = "argmin_l unary[p*L + l], lowest l on ties";

/// Neighbourhood of a grid site.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Connectivity {
    /// The 6 face neighbours: offsets (1,0,0), (0,1,0), (0,0,1) and their opposites.
    Six,
    /// The 26 face, edge and corner neighbours: the 13 lexicographically positive offsets in
    /// {−1,0,1}³ and their opposites.
    TwentySix,
}

/// The 13 lexicographically positive offsets in {−1,0,1}³ (first non-zero component > 0).
const OFFSETS_26: [[i64; 3]; 13] = [
    [0, 0, 1],
    [0, 1, -1],
    [0, 1, 0],
    [0, 1, 1],
    [1, -1, -1],
    [1, -1, 0],
    [1, -1, 1],
    [1, 0, -1],
    [1, 0, 0],
    [1, 0, 1],
    [1, 1, -1],
    [1, 1, 0],
    [1, 1, 1],
];
const OFFSETS_6: [[i64; 3]; 3] = [[1, 0, 0], [0, 1, 0], [0, 0, 1]];

impl Connectivity {
    /// The neighbour count in the format's `connectivity` field (6 or 26).
    pub fn number(self) -> u32 {
        match self {
            Connectivity::Six => 6,
            Connectivity::TwentySix => 26,
        }
    }

    /// The connectivity for 6 or 26, `None` otherwise.
    pub fn from_number(n: u64) -> Option<Self> {
        match n {
            6 => Some(Connectivity::Six),
            26 => Some(Connectivity::TwentySix),
            _ => None,
        }
    }

    /// The positive offsets (dx, dy, dz): one per unordered neighbour pair.
    pub fn offsets(self) -> &'static [[i64; 3]] {
        match self {
            Connectivity::Six => &OFFSETS_6,
            Connectivity::TwentySix => &OFFSETS_26,
        }
    }
}

/// The starting labelling of a grid problem.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum InitLabels {
    /// An explicit labelling in site order (`#sites`, each < L).
    Labels(Vec<u32>),
    /// Per-site argmin of the unary costs, lowest label on ties ([`ARGMIN_RULE`]).
    UnaryArgmin,
}

/// A validated `mrf_grid_v1` problem.
#[derive(Debug, Clone, PartialEq)]
pub struct GridProblem {
    /// Grid size `[nx, ny, nz]`, each ≥ 1.
    pub dims: [usize; 3],
    /// Number of labels L ≥ 1.
    pub num_labels: usize,
    /// Neighbourhood.
    pub connectivity: Connectivity,
    /// Weight of every neighbour pair.
    pub edge_weight: i64,
    /// Unary costs, `#sites × L`, `unary[p·L + l]`.
    pub unary: Vec<i64>,
    /// Pairwise costs V, L × L row-major: `pairwise[a·L + b]` = `V[a][b]`.
    pub pairwise: Vec<i64>,
    /// The cost that marks a forbidden label (informational; solved as a finite cost).
    pub invalid_cost: i64,
    /// The starting labelling.
    pub init_labels: InitLabels,
}

/// The result of solving a grid problem (serialisable for `motif mrf solve --json`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GridSolution {
    /// Grid size `[nx, ny, nz]`.
    pub dims: [usize; 3],
    /// Number of labels L.
    pub num_labels: usize,
    /// 6 or 26.
    pub connectivity: u32,
    /// Number of neighbour pairs.
    pub num_edges: usize,
    /// Energy of `labels_flat`, recomputed with the format's formula.
    pub energy: i64,
    /// Energy of the initial labelling.
    pub initial_energy: i64,
    /// Final labels in site order.
    pub labels_flat: Vec<u32>,
    /// Expansion passes run (see [`crate::AlphaExpansionResult::cycles`]; when converged, the
    /// last ones confirm that no move helps).
    pub cycles: usize,
    /// Energy after each pass.
    pub cycle_energies: Vec<i64>,
    /// Expansion moves solved by a graph cut.
    pub moves: usize,
    /// Moves that lowered the energy.
    pub accepted_moves: usize,
    /// Non-submodular move terms truncated (0 when V is a metric).
    pub truncated_terms: usize,
    /// Why the expansion loop stopped.
    pub termination: Termination,
    /// Sites whose final label costs `invalid_cost` or more: every label of such a site is
    /// forbidden, or the solver found no way around one (0 for a problem with a valid labelling
    /// that alpha-expansion reaches).
    #[serde(default)]
    pub forbidden_sites: usize,
    /// What makes V other than a metric ([`GridProblem::pairwise_issues`]); empty for a metric.
    #[serde(default)]
    pub pairwise_issues: Vec<String>,
    /// Solve time in milliseconds (graph construction and alpha-expansion; not file loading).
    pub solve_ms: f64,
    /// Width of the max-flow capacities the solve used, 32 or 64 bits ([`GridProblem::solve`]);
    /// 0 in reports written before it was recorded.
    #[serde(default)]
    pub capacity_bits: u32,
    /// Labels whose move graph was kept between their moves (flow recycling,
    /// [`crate::AlphaExpansionOptions::recycle_flows`]); 0 when every move was built anew.
    #[serde(default)]
    pub recycled_labels: usize,
}

/// Reads, validates and solves an `mrf_grid_v1` file.
///
/// # Errors
/// [`Error::Io`] when the file cannot be read, [`Error::Json`] / [`Error::Field`] when it is not
/// a valid problem.
pub fn solve_grid_file(path: &Path, options: &AlphaExpansionOptions) -> Result<GridSolution> {
    let bytes = std::fs::read(path).map_err(|source| Error::Io { path: path.to_path_buf(), source })?;
    GridProblem::from_json_bytes(&bytes)?.solve(options)
}

fn get<'a>(obj: &'a serde_json::Map<String, Value>, key: &str) -> Result<&'a Value> {
    obj.get(key).ok_or_else(|| Error::field(key, "missing"))
}

fn describe(v: &Value) -> String {
    let s = v.to_string();
    if s.chars().count() > 40 { format!("{}…", s.chars().take(40).collect::<String>()) } else { s }
}

/// An integer, also accepting integral floats (`3.0`) within ±2⁵³.
fn as_int(v: &Value, field: impl FnOnce() -> String) -> Result<i64> {
    if let Some(i) = v.as_i64() {
        return Ok(i);
    }
    if let Some(f) = v.as_f64().filter(|f| f.fract() == 0.0 && f.abs() <= 9_007_199_254_740_992.0) {
        return Ok(f as i64);
    }
    Err(Error::field(field(), format!("expected an integer, found {}", describe(v))))
}

fn as_count(v: &Value, field: &str, min: u64) -> Result<u64> {
    let i = as_int(v, || field.to_string())?;
    if i < min as i64 {
        return Err(Error::field(field, format!("must be at least {min}, found {i}")));
    }
    Ok(i as u64)
}

impl GridProblem {
    /// Parses and validates an `mrf_grid_v1` problem from JSON bytes.
    ///
    /// Required fields: `format`, `dims`, `num_labels`, `connectivity`, `unary`, `pairwise`.
    /// Optional: `edge_weight` (default 1), `invalid_cost` (default 1000000), `init_labels`
    /// (default the argmin rule). The descriptive string fields are ignored.
    ///
    /// # Errors
    /// [`Error::Json`] for malformed JSON, [`Error::Field`] naming the first bad field.
    pub fn from_json_bytes(bytes: &[u8]) -> Result<Self> {
        let root: Value =
            serde_json::from_slice(bytes).map_err(|e| Error::Json { message: e.to_string() })?;
        let obj = root.as_object().ok_or_else(|| Error::field("(root)", "expected a JSON object"))?;

        match get(obj, "format")? {
            Value::String(s) if s == FORMAT => {}
            v => return Err(Error::field("format", format!("expected \"{FORMAT}\", found {}", describe(v)))),
        }

        let dims_v = get(obj, "dims")?
            .as_array()
            .ok_or_else(|| Error::field("dims", "expected an array [nx, ny, nz]"))?;
        if dims_v.len() != 3 {
            return Err(Error::field(
                "dims",
                format!("expected 3 sizes [nx, ny, nz], found {}", dims_v.len()),
            ));
        }
        let mut dims = [0usize; 3];
        for (i, d) in dims_v.iter().enumerate() {
            let n = as_count(d, &format!("dims[{i}]"), 1)?;
            dims[i] = usize::try_from(n).map_err(|_| Error::field(format!("dims[{i}]"), "too large"))?;
        }
        let num_sites = dims[0]
            .checked_mul(dims[1])
            .and_then(|x| x.checked_mul(dims[2]))
            .filter(|&n| n < (u32::MAX / 32) as usize)
            .ok_or_else(|| Error::field("dims", format!("{dims:?} is too many sites")))?;

        let num_labels = as_count(get(obj, "num_labels")?, "num_labels", 1)?;
        let num_labels = usize::try_from(num_labels)
            .ok()
            .filter(|&l| l <= u32::MAX as usize)
            .ok_or_else(|| Error::field("num_labels", "too large"))?;

        let conn_v = get(obj, "connectivity")?;
        let connectivity = as_int(conn_v, || "connectivity".into())
            .ok()
            .and_then(|n| Connectivity::from_number(n as u64))
            .ok_or_else(|| {
                Error::field("connectivity", format!("expected 6 or 26, found {}", describe(conn_v)))
            })?;

        let edge_weight = match obj.get("edge_weight") {
            Some(v) => as_int(v, || "edge_weight".into())?,
            None => 1,
        };
        let invalid_cost = match obj.get("invalid_cost") {
            Some(v) => as_int(v, || "invalid_cost".into())?,
            None => 1_000_000,
        };

        let unary_v = get(obj, "unary")?
            .as_array()
            .ok_or_else(|| Error::field("unary", "expected a flat array of integers"))?;
        let expected = num_sites.checked_mul(num_labels);
        if expected != Some(unary_v.len()) {
            return Err(Error::field(
                "unary",
                format!(
                    "has {} entries, expected nx·ny·nz·num_labels = {}·{}·{}·{} = {}",
                    unary_v.len(),
                    dims[0],
                    dims[1],
                    dims[2],
                    num_labels,
                    expected.map_or("(overflow)".to_string(), |e| e.to_string())
                ),
            ));
        }
        let unary = unary_v
            .iter()
            .enumerate()
            .map(|(i, v)| as_int(v, || format!("unary[{i}]")))
            .collect::<Result<Vec<i64>>>()?;

        let rows = get(obj, "pairwise")?
            .as_array()
            .ok_or_else(|| Error::field("pairwise", "expected an L×L array"))?;
        if rows.len() != num_labels {
            return Err(Error::field(
                "pairwise",
                format!("has {} rows, expected num_labels = {num_labels}", rows.len()),
            ));
        }
        // Check every row's length before allocating L² entries: they are then all in the JSON.
        for (a, row) in rows.iter().enumerate() {
            if row.as_array().is_none_or(|r| r.len() != num_labels) {
                return Err(Error::field(
                    format!("pairwise[{a}]"),
                    format!("expected {num_labels} integers"),
                ));
            }
        }
        let mut pairwise = Vec::with_capacity(num_labels * num_labels);
        for (a, row) in rows.iter().enumerate() {
            for (b, v) in row.as_array().into_iter().flatten().enumerate() {
                pairwise.push(as_int(v, || format!("pairwise[{a}][{b}]"))?);
            }
        }

        let init_labels = match obj.get("init_labels") {
            None => InitLabels::UnaryArgmin,
            Some(Value::String(s)) => {
                if s.trim_start().to_ascii_lowercase().starts_with("argmin") {
                    InitLabels::UnaryArgmin
                } else {
                    return Err(Error::field(
                        "init_labels",
                        format!("unknown rule {s:?}; expected a list of labels or \"{ARGMIN_RULE}\""),
                    ));
                }
            }
            Some(Value::Array(list)) => {
                if list.len() != num_sites {
                    return Err(Error::field(
                        "init_labels",
                        format!("has {} labels, expected one per site ({num_sites})", list.len()),
                    ));
                }
                let mut labels = Vec::with_capacity(list.len());
                for (p, v) in list.iter().enumerate() {
                    let l = as_int(v, || format!("init_labels[{p}]"))?;
                    if l < 0 || l as u64 >= num_labels as u64 {
                        return Err(Error::field(
                            format!("init_labels[{p}]"),
                            format!("label {l} outside 0..{num_labels}"),
                        ));
                    }
                    labels.push(l as u32);
                }
                InitLabels::Labels(labels)
            }
            Some(v) => {
                return Err(Error::field(
                    "init_labels",
                    format!("expected a list of labels or a rule string, found {}", describe(v)),
                ));
            }
        };

        let problem = GridProblem {
            dims,
            num_labels,
            connectivity,
            edge_weight,
            unary,
            pairwise,
            invalid_cost,
            init_labels,
        };
        problem.validate()?;
        Ok(problem)
    }

    /// Parses and validates an `mrf_grid_v1` problem from a JSON string.
    ///
    /// # Errors
    /// As [`GridProblem::from_json_bytes`].
    pub fn from_json_str(s: &str) -> Result<Self> {
        Self::from_json_bytes(s.as_bytes())
    }

    /// Checks that the sizes agree and that no energy can overflow 64-bit integers. Problems from
    /// [`GridProblem::from_json_bytes`] and [`generate_grid`] are already valid; call this after
    /// building or editing one by hand.
    ///
    /// # Errors
    /// [`Error::Field`] naming the inconsistent field.
    pub fn validate(&self) -> Result<()> {
        if self.dims.contains(&0) {
            return Err(Error::field("dims", format!("{:?} has a zero size", self.dims)));
        }
        let num_sites = self
            .dims
            .iter()
            .try_fold(1usize, |acc, &d| acc.checked_mul(d))
            .filter(|&n| n < (u32::MAX / 32) as usize)
            .ok_or_else(|| Error::field("dims", format!("{:?} is too many sites", self.dims)))?;
        if self.num_labels == 0 || self.num_labels > u32::MAX as usize {
            return Err(Error::field("num_labels", format!("{} is not in 1..=2^32-1", self.num_labels)));
        }
        if num_sites.checked_mul(self.num_labels) != Some(self.unary.len()) {
            return Err(Error::field(
                "unary",
                format!("has {} entries, expected {num_sites}·{}", self.unary.len(), self.num_labels),
            ));
        }
        if self.num_labels.checked_mul(self.num_labels) != Some(self.pairwise.len()) {
            return Err(Error::field(
                "pairwise",
                format!("has {} entries, expected {1}×{1}", self.pairwise.len(), self.num_labels),
            ));
        }
        if let InitLabels::Labels(l) = &self.init_labels {
            if l.len() != num_sites {
                return Err(Error::field(
                    "init_labels",
                    format!("has {} labels for {num_sites} sites", l.len()),
                ));
            }
            if let Some(p) = l.iter().position(|&x| x as usize >= self.num_labels) {
                return Err(Error::field(
                    format!("init_labels[{p}]"),
                    format!("label {} out of range", l[p]),
                ));
            }
        }
        if self.edge_weight < 0 {
            return Err(Error::field(
                "edge_weight",
                format!(
                    "{} is negative: alpha-expansion needs non-negative pairwise costs (a metric V times a weight ≥ 0)",
                    self.edge_weight
                ),
            ));
        }
        if self.invalid_cost <= 0 {
            return Err(Error::field(
                "invalid_cost",
                format!(
                    "{} must be positive (the large cost that marks a forbidden label)",
                    self.invalid_cost
                ),
            ));
        }
        // Worst-case |energy| (and every partial sum the solver forms) must fit comfortably.
        let max_unary = self.unary.iter().map(|x| x.unsigned_abs() as u128).max().unwrap_or(0);
        let max_pair = self.pairwise.iter().map(|x| x.unsigned_abs() as u128).max().unwrap_or(0);
        let pairs = num_sites as u128 * self.connectivity.offsets().len() as u128;
        let unary_bound = max_unary.saturating_mul(2 * num_sites as u128);
        let pair_bound =
            (4 * self.edge_weight.unsigned_abs() as u128).saturating_mul(max_pair).saturating_mul(pairs);
        if unary_bound.saturating_add(pair_bound) > (1u128 << 62) {
            // Name the part that makes the bound too large.
            let (field, what) = if pair_bound >= unary_bound {
                ("pairwise", "pairwise costs (times edge_weight)")
            } else {
                ("unary", "unary costs")
            };
            return Err(Error::field(
                field,
                format!(
                    "{what} are too large: energies of this problem could overflow 64-bit integers; scale them down"
                ),
            ));
        }
        Ok(())
    }

    /// What makes the pairwise matrix V something other than a metric, for a note: an asymmetric
    /// entry, a non-zero diagonal, a negative entry, or a violated triangle inequality (the first
    /// of each found). Alpha-expansion is exact in its moves only for a metric; other terms are
    /// truncated ([`GridSolution::truncated_terms`] counts those the moves met).
    pub fn pairwise_issues(&self) -> Vec<String> {
        let l = self.num_labels;
        let v = |a: usize, b: usize| self.pairwise[a * l + b];
        let mut out = Vec::new();
        if let Some(a) = (0..l).find(|&a| v(a, a) != 0) {
            out.push(format!("V[{a}][{a}] = {} is not 0", v(a, a)));
        }
        if let Some((a, b)) = (0..l).flat_map(|a| (0..l).map(move |b| (a, b))).find(|&(a, b)| v(a, b) < 0) {
            out.push(format!("V[{a}][{b}] = {} is negative", v(a, b)));
        }
        if let Some((a, b)) =
            (0..l).flat_map(|a| (a + 1..l).map(move |b| (a, b))).find(|&(a, b)| v(a, b) != v(b, a))
        {
            out.push(format!("V is not symmetric: V[{a}][{b}] = {}, V[{b}][{a}] = {}", v(a, b), v(b, a)));
        }
        // O(L³): at most 64³ for the shipped problems; skipped above 128 labels.
        if l <= 128 {
            'outer: for a in 0..l {
                for b in 0..l {
                    for c in 0..l {
                        if v(a, c) as i128 > v(a, b) as i128 + v(b, c) as i128 {
                            out.push(format!(
                                "V breaks the triangle inequality: V[{a}][{c}] = {} > V[{a}][{b}] + V[{b}][{c}] = {}",
                                v(a, c),
                                v(a, b) as i128 + v(b, c) as i128
                            ));
                            break 'outer;
                        }
                    }
                }
            }
        }
        out
    }

    /// Number of sites nx·ny·nz.
    pub fn num_sites(&self) -> usize {
        self.dims[0] * self.dims[1] * self.dims[2]
    }

    /// The neighbour pairs `[p, q]` (p < q), site-major, offsets in the order of
    /// [`Connectivity::offsets`].
    pub fn edges(&self) -> Vec<[u32; 2]> {
        let [nx, ny, nz] = self.dims.map(|d| d as i64);
        let offsets = self.connectivity.offsets();
        let mut edges = Vec::with_capacity(self.num_sites() * offsets.len());
        for x in 0..nx {
            for y in 0..ny {
                for z in 0..nz {
                    let p = (x * ny + y) * nz + z;
                    for &[dx, dy, dz] in offsets {
                        let (qx, qy, qz) = (x + dx, y + dy, z + dz);
                        if (0..nx).contains(&qx) && (0..ny).contains(&qy) && (0..nz).contains(&qz) {
                            let q = (qx * ny + qy) * nz + qz;
                            edges.push([p as u32, q as u32]);
                        }
                    }
                }
            }
        }
        edges
    }

    /// The starting labelling (explicit, or the argmin rule applied).
    pub fn initial_labels(&self) -> Vec<u32> {
        match &self.init_labels {
            InitLabels::Labels(l) => l.clone(),
            InitLabels::UnaryArgmin => self
                .unary
                .chunks_exact(self.num_labels)
                .map(|row| {
                    let mut best = 0;
                    for (l, &c) in row.iter().enumerate() {
                        if c < row[best] {
                            best = l;
                        }
                    }
                    best as u32
                })
                .collect(),
        }
    }

    /// The energy of `labels` with the format's formula.
    ///
    /// # Errors
    /// [`Error::Field`] for an invalid problem, [`Error::InvalidEnergy`] when `labels` has the
    /// wrong length or a label out of range.
    pub fn energy(&self, labels: &[u32]) -> Result<i64> {
        self.validate()?;
        self.energy_with_edges(labels, &self.edges())
    }

    fn energy_with_edges(&self, labels: &[u32], edges: &[[u32; 2]]) -> Result<i64> {
        let l = self.num_labels;
        if labels.len() != self.num_sites() {
            return Err(Error::energy(format!("{} labels for {} sites", labels.len(), self.num_sites())));
        }
        if let Some(p) = labels.iter().position(|&x| x as usize >= l) {
            return Err(Error::energy(format!("site {p} has label {} outside 0..{l}", labels[p])));
        }
        let unary: i64 = labels.iter().enumerate().map(|(p, &x)| self.unary[p * l + x as usize]).sum();
        let pair: i64 = edges
            .iter()
            .map(|&[p, q]| self.pairwise[labels[p as usize] as usize * l + labels[q as usize] as usize])
            .sum();
        Ok(unary + self.edge_weight * pair)
    }

    /// Solves the problem by alpha-expansion from its initial labelling, on 32-bit capacities
    /// when every sum the solver forms provably fits them (non-negative costs, the bound of
    /// `fits_32_bit_capacities`: the shipped and generated problems do), else on 64-bit ones.
    /// Both give the same moves and labels; the smaller arcs and nodes make a solve 5–9% faster
    /// (docs/retarget.md).
    ///
    /// # Errors
    /// Only for an invalid problem (see [`GridProblem::validate`]).
    pub fn solve(&self, options: &AlphaExpansionOptions) -> Result<GridSolution> {
        self.validate()?;
        let start = Instant::now();
        let l = self.num_labels;
        let edges = self.edges();
        let init = self.initial_labels();
        let initial_energy = self.energy_with_edges(&init, &edges)?;
        // 32-bit capacities shrink the solver's nodes and arcs (a solve 5–9% faster); they are
        // used only when every sum the solver forms provably fits.
        let narrow = self.fits_32_bit_capacities(initial_energy, edges.len());
        let r = if narrow {
            self.expand_with(&edges, &init, options, |v| v as i32, i64::from)?
        } else {
            self.expand_with(&edges, &init, options, |v| v, |v| v)?
        };
        let solve_ms = start.elapsed().as_secs_f64() * 1e3;
        let energy = self.energy_with_edges(&r.labels, &edges)?;
        let forbidden_sites = (0..self.num_sites())
            .filter(|&p| self.unary[p * l + r.labels[p] as usize] >= self.invalid_cost)
            .count();
        Ok(GridSolution {
            dims: self.dims,
            num_labels: l,
            connectivity: self.connectivity.number(),
            num_edges: edges.len(),
            energy,
            initial_energy,
            labels_flat: r.labels,
            cycles: r.cycles,
            cycle_energies: r.cycle_energies,
            moves: r.moves,
            accepted_moves: r.accepted_moves,
            truncated_terms: r.truncated_terms,
            termination: r.termination,
            forbidden_sites,
            pairwise_issues: self.pairwise_issues(),
            solve_ms,
            capacity_bits: if narrow { 32 } else { 64 },
            recycled_labels: r.recycled_labels,
        })
    }

    /// Alpha-expansion from `init` with capacities of type `C`: costs converted by `to`, energies
    /// back by `back`.
    fn expand_with<C: Capacity>(
        &self,
        edges: &[[u32; 2]],
        init: &[u32],
        options: &AlphaExpansionOptions,
        to: impl Fn(i64) -> C,
        back: impl Fn(C) -> i64,
    ) -> Result<AlphaExpansionResult<i64>> {
        let l = self.num_labels;
        let weighted: Vec<C> = self.pairwise.iter().map(|&v| to(self.edge_weight * v)).collect();
        let unary: Vec<C> = self.unary.iter().map(|&v| to(v)).collect();
        let energy = MrfEnergy::new(
            self.num_sites(),
            l,
            edges,
            |p, a| unary[p * l + a],
            |_, _, a, b| weighted[a * l + b],
        );
        let r = AlphaExpansion::<C>::new().solve(&energy, init, options)?;
        Ok(AlphaExpansionResult {
            labels: r.labels,
            energy: back(r.energy),
            initial_energy: back(r.initial_energy),
            cycles: r.cycles,
            cycle_energies: r.cycle_energies.into_iter().map(back).collect(),
            moves: r.moves,
            accepted_moves: r.accepted_moves,
            truncated_terms: r.truncated_terms,
            termination: r.termination,
            elapsed_ms: r.elapsed_ms,
            recycled_labels: r.recycled_labels,
        })
    }

    /// Whether alpha-expansion on this problem, from a labelling of energy `initial_energy`, can
    /// use 32-bit capacities: every cost is non-negative and every sum the solver forms stays
    /// below 2³¹ / 4. With non-negative costs the energy only falls from `initial_energy`; a
    /// move's flow and the sum of its sink capacities are at most the current labelling's unary
    /// costs plus four times each edge's largest pairwise cost (≤ `initial_energy` + 4·|E|·w);
    /// one node's terminal capacity is at most one unary cost plus 4·w per incident edge; one
    /// arc's, 4·w (w: `edge_weight` times the largest pairwise cost).
    fn fits_32_bit_capacities(&self, initial_energy: i64, num_edges: usize) -> bool {
        if self.unary.iter().any(|&u| u < 0) || self.pairwise.iter().any(|&v| v < 0) || initial_energy < 0 {
            return false;
        }
        let max_unary = self.unary.iter().copied().max().unwrap_or(0) as i128;
        let w = self.edge_weight as i128 * self.pairwise.iter().copied().max().unwrap_or(0) as i128;
        let degree = 2 * self.connectivity.offsets().len() as i128;
        let flow = initial_energy as i128 + 4 * num_edges as i128 * w;
        let node = max_unary + 4 * degree * w;
        2 * flow + 2 * node <= (i32::MAX / 4) as i128
    }

    /// The problem as `mrf_grid_v1` JSON, with the descriptive fields of the shipped files.
    pub fn to_json_string(&self) -> String {
        #[derive(Serialize)]
        struct Out<'a> {
            format: &'a str,
            dims: [usize; 3],
            num_labels: usize,
            connectivity: u32,
            edge_weight: i64,
            site_index: &'a str,
            unary_layout: &'a str,
            unary: &'a [i64],
            pairwise: Vec<&'a [i64]>,
            invalid_cost: i64,
            energy: &'a str,
            neighbours: &'a str,
            init_labels: Value,
        }
        let out = Out {
            format: FORMAT,
            dims: self.dims,
            num_labels: self.num_labels,
            connectivity: self.connectivity.number(),
            edge_weight: self.edge_weight,
            site_index: "p = (x*ny + y)*nz + z (C order, z fastest)",
            unary_layout: "unary[p*num_labels + l] = D[p][l], int",
            unary: &self.unary,
            pairwise: self.pairwise.chunks(self.num_labels.max(1)).collect(),
            invalid_cost: self.invalid_cost,
            energy: "E = sum_p unary[p*L + x_p] + sum over unordered neighbour pairs {p,q} of pairwise[x_p][x_q]",
            neighbours: "6: offsets (1,0,0),(0,1,0),(0,0,1); 26: all 13 lexicographically positive offsets in {-1,0,1}^3",
            init_labels: match &self.init_labels {
                InitLabels::Labels(l) => Value::from(l.clone()),
                InitLabels::UnaryArgmin => Value::from(ARGMIN_RULE),
            },
        };
        // Serialising plain numbers and strings cannot fail.
        serde_json::to_string(&out).unwrap_or_default()
    }
}

/// Generates a benchmark problem of the same kind as the shipped example
/// (`mrf_10x10x10_L8_c6.json`): a smooth hidden label field g (three random plane waves),
/// unary costs `4·|l − g_p| + U{0..24}` with each entry forbidden (`invalid_cost` = 1000000) with
/// probability 0.1 (never all labels of a site), truncated-linear pairwise costs
/// `V(a, b) = 10·min(|a − b|, 4)`, `edge_weight` 1, and the argmin initial labelling.
/// Deterministic for a given seed. It reproduces the example's statistics (cost range, 10 %
/// invalid entries, spatial correlation), not its exact numbers.
///
/// # Panics
/// If a size or `num_labels` is 0.
pub fn generate_grid(
    dims: [usize; 3],
    num_labels: usize,
    connectivity: Connectivity,
    seed: u64,
) -> GridProblem {
    assert!(!dims.contains(&0) && num_labels > 0, "generate_grid needs non-zero sizes and labels");
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let waves: Vec<([f64; 3], f64)> = (0..3)
        .map(|_| {
            let f = [0, 1, 2].map(|i| rng.random_range(0.5..2.0) / dims[i] as f64);
            (f, rng.random_range(0.0..std::f64::consts::TAU))
        })
        .collect();
    let invalid_cost = 1_000_000;
    let l = num_labels;
    let mut unary = Vec::with_capacity(dims[0] * dims[1] * dims[2] * l);
    for x in 0..dims[0] {
        for y in 0..dims[1] {
            for z in 0..dims[2] {
                let pos = [x as f64, y as f64, z as f64];
                let s: f64 = waves
                    .iter()
                    .map(|(f, phase)| {
                        (std::f64::consts::TAU * (f[0] * pos[0] + f[1] * pos[1] + f[2] * pos[2]) + phase)
                            .sin()
                    })
                    .sum::<f64>()
                    / 3.0;
                let g = (s + 1.0) * 0.5 * (l - 1) as f64;
                let row_start = unary.len();
                for label in 0..l {
                    let cost = (4.0 * (label as f64 - g).abs()).round() as i64 + rng.random_range(0..=24);
                    unary.push(if rng.random_bool(0.1) { invalid_cost } else { cost });
                }
                if unary[row_start..].iter().all(|&c| c == invalid_cost) {
                    let label = rng.random_range(0..l);
                    unary[row_start + label] = (4.0 * (label as f64 - g).abs()).round() as i64;
                }
            }
        }
    }
    let pairwise = (0..l * l).map(|i| 10 * ((i / l).abs_diff(i % l).min(4) as i64)).collect();
    GridProblem {
        dims,
        num_labels,
        connectivity,
        edge_weight: 1,
        unary,
        pairwise,
        invalid_cost,
        init_labels: InitLabels::UnaryArgmin,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_benchmark_grids_fit_32_bit_capacities_and_large_or_negative_costs_do_not() {
        for (dims, labels, conn) in
            [([30, 30, 30], 64, Connectivity::Six), ([20, 20, 20], 30, Connectivity::TwentySix)]
        {
            let p = generate_grid(dims, labels, conn, 1);
            let edges = p.edges();
            let e = p.energy_with_edges(&p.initial_labels(), &edges).unwrap();
            assert!(p.fits_32_bit_capacities(e, edges.len()), "{dims:?}");
            // The bound is on the initial energy: a start near 2³¹ / 8 does not fit.
            assert!(!p.fits_32_bit_capacities(i64::from(i32::MAX / 8), edges.len()), "{dims:?}");
        }
        let mut p = generate_grid([4, 4, 4], 5, Connectivity::Six, 2);
        let edges = p.edges();
        let e = p.energy_with_edges(&p.initial_labels(), &edges).unwrap();
        assert!(p.fits_32_bit_capacities(e, edges.len()));
        p.unary[3] = -1;
        assert!(!p.fits_32_bit_capacities(e, edges.len()), "a negative cost");
        p.unary[3] = 1 << 31;
        assert!(!p.fits_32_bit_capacities(e, edges.len()), "one cost beyond 32 bits");
        p.unary[3] = 0;
        p.pairwise[1] = 1 << 28;
        assert!(!p.fits_32_bit_capacities(e, edges.len()), "a pairwise cost that 4·|E| times overflows");
    }
}
