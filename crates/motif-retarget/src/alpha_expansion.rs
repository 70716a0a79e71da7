//! Multi-label MRF energy minimisation by alpha-expansion (thesis 4.2.2, eq. 4.3).
//!
//! Minimises E(x) = Σ_p D_p(x_p) + Σ_{(p,q)} w_pq · V_pq(x_p, x_q) over labellings
//! x ∈ {0..L}^N of an arbitrary graph (an edge list), following Y. Boykov, O. Veksler and
//! R. Zabih, "Fast approximate energy minimization via graph cuts", IEEE TPAMI 23(11), 2001.
//! Each expansion move lets every site either keep its label or switch to one label α; the best
//! move is a minimum cut (V. Kolmogorov and R. Zabih, "What energy functions can be minimized via
//! graph cuts?", TPAMI 26(2), 2004), computed with the [`crate::maxflow`] Boykov–Kolmogorov
//! solver. Moves are scheduled in passes over the labels until the labelling is a local minimum of
//! every expansion move — by default with GCO's strategic queues ([`CycleStrategy::Queue`]),
//! which retry the labels whose moves succeed and set the others aside; a move is applied only
//! when it lowers the energy, and among equally good cuts the one switching the most sites to α
//! is taken ([`TieBreak::MostAlpha`]). With this schedule Motif takes the same moves as GCO 3.0
//! and reaches the same energies on the `mrf_grid_v1` benchmarks. Several moves can be solved at
//! once on several threads without changing the result (see [`AlphaExpansion`]).
//!
//! Pairwise costs come from a callback `V(p, q, lp, lq)` evaluated per edge, so they may depend
//! on the sites (the retargeting term of eq. 4.4 does). A move's binary term
//! (A, B, C, D) = (V(x_p, x_q), V(x_p, α), V(α, x_q), V(α, α)) is representable when
//! A + D ≤ B + C, which holds for every metric V. When a term violates it, the move uses a
//! truncated term (Rother, Kumar, Kolmogorov, Blake, "Digital tapestry", CVPR 2005): B is raised
//! to A + D − C, an upper bound that leaves the current labelling's energy unchanged, so the true
//! energy still never increases; such a move is scored with the true energy and applied only if
//! that drops. Violations are counted in [`AlphaExpansionResult::truncated_terms`]. Each term
//! becomes arcs in both directions where possible (a term that only penalises disagreement puts
//! no flow through the terminals).
//!
//! Guarantees (BVZ 2001, metric V): the result is a local minimum with respect to every single
//! expansion move, within a factor 2·c of the global minimum, c = max_{a≠b} V(a,b) /
//! min_{a≠b} V(a,b) (2 for Potts); with two labels and a submodular V it is the global minimum.
//!
//! Flow recycling (integer energies, [`AlphaExpansionOptions::recycle_flows`]): each label keeps
//! its move graph, over every site, and its next move starts from the last one's flow and search
//! trees, after updating only the terms of the sites whose label changed since and of their
//! edges (dynamic graph cuts: P. Kohli and P. Torr, ICCV 2005; reused across the moves of one
//! label as in K. Alahari, P. Kohli and P. Torr, "Reduce, reuse & recycle", CVPR 2008). Near
//! convergence few labels change between two moves of the same label, so those moves cost a
//! fraction of a fresh one; the moves taken, and so the result, are those of fresh graphs.
//! On the 30³ 64-label `mrf_grid_v1` benchmark this makes the solve about 2.6 times faster
//! (docs/retarget.md).
//!
//! Costs: a unary +∞ (floating-point energies) forbids the label at that site: moves never switch
//! a site to a forbidden label, and such sites stay out of the move's graph (which keeps moves
//! small when few sites can take α, as with the offset labels of 4.2.2). Other +∞ costs are
//! replaced inside the moves by [`AlphaExpansionOptions::infinite_cost`]; NaN and −∞ are errors.
//! The reported energies use the callbacks' own values (so they are +∞ for an infeasible
//! labelling).

use std::time::Instant;

use rand::SeedableRng;
use rand::seq::SliceRandom;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::maxflow::{Capacity, Graph, Segment};

/// The order in which labels are tried within a cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LabelOrder {
    /// 0, 1, …, L−1 in every cycle (GCO's default).
    #[default]
    Sequential,
    /// A random permutation from a ChaCha8 generator seeded with `seed` (reproducible): a fresh
    /// one in every cycle with [`CycleStrategy::Full`] and [`CycleStrategy::Adaptive`], one per
    /// solve with [`CycleStrategy::Queue`] (as GCO permutes its label table once).
    Random {
        /// Seed of the permutation generator.
        seed: u64,
    },
}

/// Which labels a cycle tries.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CycleStrategy {
    /// Every cycle tries every label (BVZ 2001).
    Full,
    /// After a cycle that lowered the energy, the next cycle tries only the labels whose move
    /// succeeded in it; when such a cycle finds nothing, a full cycle follows, and the solve ends
    /// only after a full cycle without improvement, so the result is still a local minimum of
    /// every expansion move. A third fewer moves than [`CycleStrategy::Full`] on the generated
    /// benchmark grids (same final labellings there), but it may also take a longer path to a
    /// different local minimum (more moves on the retargeting-shaped benchmark).
    Adaptive,
    /// GCO's "strategic" expansion (`expansion(-1)` in GCO 3.0): labels whose move fails leave
    /// the current queue; when fewer than half of a pass's moves succeed, the next passes focus
    /// on the successful ones in a smaller queue, and when a pass of a queue succeeds nowhere the
    /// labels set aside in the enclosing queue are tried again. The solve ends when the outermost
    /// queue has a pass without success, so the result is a local minimum of every expansion
    /// move. Together with [`TieBreak::MostAlpha`] and [`LabelOrder::Sequential`] it takes
    /// GCO's sequence of accepted moves (Motif skips moves known to fail that GCO still solves,
    /// so the counts of solved moves differ). The default: on the `mrf_grid_v1` benchmark problems it
    /// reaches GCO's energies, and on the retargeting MRFs of 4.4 it needs about half the moves
    /// of [`CycleStrategy::Full`] (most labels are never used there, and their moves are not
    /// retried until the used ones settle).
    #[default]
    Queue,
}

/// Which of several equally good cuts an expansion move applies.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TieBreak {
    /// Switch every site that some minimum cut switches (the largest α region; GCO's choice:
    /// its `applyNewLabeling` switches the variables that read 0, and its max-flow reports free
    /// nodes as source-side, i.e. 0).
    #[default]
    MostAlpha,
    /// Switch only the sites that every minimum cut switches.
    FewestAlpha,
}

impl TieBreak {
    /// The side of the cut a move puts the sites in neither search tree on (free: either side
    /// gives a minimum cut); the sink side switches to α.
    fn free_side(self) -> Segment {
        match self {
            TieBreak::MostAlpha => Segment::Sink,
            TieBreak::FewestAlpha => Segment::Source,
        }
    }
}

/// Options of [`alpha_expansion`] and [`AlphaExpansion::solve`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct AlphaExpansionOptions {
    /// Maximum number of cycles of the graph-cut optimisation of thesis eq. 4.3 (section 4.2.2):
    /// passes over every label with [`CycleStrategy::Full`] and [`CycleStrategy::Adaptive`],
    /// passes of the outermost queue with [`CycleStrategy::Queue`] (the focused passes on smaller
    /// queues in between do not count). Default 100: alpha-expansion typically converges in 2–8
    /// such cycles, so the limit only bounds pathological runs (GCO's `expansion()` runs until
    /// convergence). 0 returns the initial labelling.
    pub max_cycles: usize,
    /// Order of the labels within a cycle. Default [`LabelOrder::Sequential`].
    pub label_order: LabelOrder,
    /// Which labels each cycle tries. Default [`CycleStrategy::Queue`].
    pub cycles: CycleStrategy,
    /// Which minimum cut a move applies when several are optimal. Default
    /// [`TieBreak::MostAlpha`].
    pub ties: TieBreak,
    /// Finite value that replaces +∞ costs inside the moves (floating-point energies only).
    /// It must exceed the largest finite energy of a labelling you care about; keep it well below
    /// 1e15 so that f64 sums still resolve the finite costs. Default 1e9 (the retargeting energy
    /// of eq. 4.3 is a sum of at most ~10⁴ descriptor distances). Integer energies never hold
    /// infinities and ignore this field.
    pub infinite_cost: f64,
    /// Keep each label's move graph and start its next move from the last one's flow (see the
    /// module docs, "Flow recycling"), for integer capacities and as many labels as 256 MB hold.
    /// The moves and the result are the same as without; only the time changes. Default true;
    /// false builds every move's graph anew (as GCO does).
    pub recycle_flows: bool,
}

impl Default for AlphaExpansionOptions {
    fn default() -> Self {
        AlphaExpansionOptions {
            max_cycles: 100,
            label_order: LabelOrder::Sequential,
            cycles: CycleStrategy::Queue,
            ties: TieBreak::MostAlpha,
            infinite_cost: 1e9,
            recycle_flows: true,
        }
    }
}

/// Why the expansion loop stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Termination {
    /// No move can lower the energy any more (a whole cycle, or with [`CycleStrategy::Queue`] a
    /// pass of the outermost queue after every focused queue, found nothing): the labelling is a
    /// local minimum with respect to every expansion move.
    Converged,
    /// [`AlphaExpansionOptions::max_cycles`] cycles were run.
    MaxCycles,
}

impl Termination {
    /// How reports spell it: `converged` or `max_cycles`.
    pub fn as_str(self) -> &'static str {
        match self {
            Termination::Converged => "converged",
            Termination::MaxCycles => "max_cycles",
        }
    }
}

/// The outcome of alpha-expansion.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AlphaExpansionResult<C> {
    /// Final label of every site (`#sites`).
    pub labels: Vec<u32>,
    /// Energy of `labels`, recomputed from the callbacks.
    pub energy: C,
    /// Energy of the initial labelling, from the callbacks.
    pub initial_energy: C,
    /// Number of passes run, of every kind (full, adaptive, or queue passes of any size; when
    /// converged, the last ones confirm that no move helps).
    pub cycles: usize,
    /// Energy after each pass (with +∞ costs replaced by the `infinite_cost` option).
    pub cycle_energies: Vec<C>,
    /// Number of expansion moves solved by a graph cut (moves known to fail are skipped).
    pub moves: usize,
    /// Number of moves that lowered the energy.
    pub accepted_moves: usize,
    /// Number of pairwise move terms that violated A + D ≤ B + C and were truncated, summed over
    /// all moves (0 for metric pairwise costs).
    pub truncated_terms: usize,
    /// Why the loop stopped.
    pub termination: Termination,
    /// Wall-clock time of the solve, in milliseconds.
    pub elapsed_ms: f64,
    /// Labels whose move graph was kept between their moves
    /// ([`AlphaExpansionOptions::recycle_flows`]); 0 when every move was built anew.
    #[serde(default)]
    pub recycled_labels: usize,
}

/// A multi-label energy over a graph: sites `0..num_sites`, labels `0..num_labels`, unary costs
/// `unary(p, l)` = D_p(l), pairwise costs `pairwise(p, q, lp, lq)` = V_pq(lp, lq) for every
/// edge `[p, q]` of `edges`, optionally scaled by per-edge weights w_pq.
///
/// The callbacks are called many times per move; keep them cheap (precompute tables).
#[derive(Debug, Clone)]
pub struct MrfEnergy<'a, C, D, V> {
    /// Number of sites N.
    pub num_sites: usize,
    /// Number of labels L.
    pub num_labels: usize,
    /// Neighbour pairs `[p, q]` (p ≠ q, each < N); a pair listed twice counts twice.
    pub edges: &'a [[u32; 2]],
    /// Optional weights w_pq ≥ 0, one per edge (`edges.len()`); `None` means all 1.
    pub edge_weights: Option<&'a [C]>,
    /// D(p, l): the cost of giving site p label l.
    pub unary: D,
    /// V(p, q, lp, lq): the cost of labels (lp, lq) on edge [p, q].
    pub pairwise: V,
}

impl<'a, C, D, V> MrfEnergy<'a, C, D, V>
where
    C: Capacity,
    D: Fn(usize, usize) -> C,
    V: Fn(usize, usize, usize, usize) -> C,
{
    /// An energy with unit edge weights.
    pub fn new(num_sites: usize, num_labels: usize, edges: &'a [[u32; 2]], unary: D, pairwise: V) -> Self {
        MrfEnergy { num_sites, num_labels, edges, edge_weights: None, unary, pairwise }
    }

    /// The same energy with per-edge weights w_pq.
    pub fn with_edge_weights(mut self, weights: &'a [C]) -> Self {
        self.edge_weights = Some(weights);
        self
    }

    #[inline]
    fn weight(&self, e: usize) -> C {
        match self.edge_weights {
            Some(w) => w[e],
            None => C::ONE,
        }
    }

    /// Checks sizes, indices and weights.
    fn validate(&self) -> Result<()> {
        if self.num_labels == 0 {
            return Err(Error::energy("num_labels is 0; an MRF needs at least one label"));
        }
        if self.num_labels > u32::MAX as usize {
            return Err(Error::energy(format!("num_labels {} exceeds u32", self.num_labels)));
        }
        if self.num_sites >= (u32::MAX - 3) as usize {
            return Err(Error::energy(format!("num_sites {} exceeds the graph limit", self.num_sites)));
        }
        if 2 * self.edges.len() >= (u32::MAX - 3) as usize {
            return Err(Error::energy(format!("{} edges exceed the graph limit", self.edges.len())));
        }
        for (k, &[p, q]) in self.edges.iter().enumerate() {
            if p as usize >= self.num_sites || q as usize >= self.num_sites {
                return Err(Error::energy(format!(
                    "edge {k} = [{p}, {q}] names a site outside 0..{}",
                    self.num_sites
                )));
            }
            if p == q {
                return Err(Error::energy(format!("edge {k} = [{p}, {q}] joins a site to itself")));
            }
        }
        if let Some(w) = self.edge_weights {
            if w.len() != self.edges.len() {
                return Err(Error::energy(format!(
                    "{} edge weights for {} edges",
                    w.len(),
                    self.edges.len()
                )));
            }
            if let Some(k) = w.iter().position(|&x| x.is_nan() || x < C::ZERO || x.is_infinite()) {
                return Err(Error::energy(format!(
                    "edge weight {k} is {:?}; weights must be finite and >= 0",
                    w[k]
                )));
            }
        }
        Ok(())
    }

    fn validate_labels(&self, labels: &[u32], what: &str) -> Result<()> {
        if labels.len() != self.num_sites {
            return Err(Error::energy(format!(
                "{what} has {} labels for {} sites",
                labels.len(),
                self.num_sites
            )));
        }
        if let Some(p) = labels.iter().position(|&l| l as usize >= self.num_labels) {
            return Err(Error::energy(format!(
                "{what}: site {p} has label {} outside 0..{}",
                labels[p], self.num_labels
            )));
        }
        Ok(())
    }

    /// D(p, l) with +∞ replaced by `hard`; NaN and −∞ are errors.
    #[inline]
    fn unary_clamped(&self, p: usize, l: usize, hard: C) -> Result<C> {
        let v = (self.unary)(p, l);
        if v.is_nan() || v.is_infinite() {
            if v.is_infinite() && v > C::ZERO {
                return Ok(hard);
            }
            return Err(Error::NonFiniteCost {
                term: "unary",
                value: format!("{v:?}"),
                location: format!("site {p}, label {l}"),
            });
        }
        Ok(v)
    }

    /// w_pq · V(p, q, lp, lq) with +∞ replaced by `hard`; NaN and −∞ are errors.
    #[inline]
    fn pairwise_clamped(&self, e: usize, p: usize, q: usize, lp: usize, lq: usize, hard: C) -> Result<C> {
        let mut v = (self.pairwise)(p, q, lp, lq);
        if v.is_nan() || v.is_infinite() {
            if v.is_infinite() && v > C::ZERO {
                v = hard;
            } else {
                return Err(Error::NonFiniteCost {
                    term: "pairwise",
                    value: format!("{v:?}"),
                    location: format!("edge {e} = [{p}, {q}], labels ({lp}, {lq})"),
                });
            }
        }
        match self.edge_weights {
            None => Ok(v),
            Some(w) => Ok(w[e] * v),
        }
    }

    /// Energy with +∞ costs replaced by `hard`.
    fn energy_clamped(&self, labels: &[u32], hard: C) -> Result<C> {
        let mut e = C::ZERO;
        for (p, &l) in labels.iter().enumerate() {
            e += self.unary_clamped(p, l as usize, hard)?;
        }
        for (k, &[p, q]) in self.edges.iter().enumerate() {
            let (p, q) = (p as usize, q as usize);
            e += self.pairwise_clamped(k, p, q, labels[p] as usize, labels[q] as usize, hard)?;
        }
        Ok(e)
    }
}

/// Dense unary costs as a callback: `costs[p * num_labels + l]` = D_p(l) (`#sites × L`, site
/// major).
pub fn dense_unary<C: Copy>(costs: &[C], num_labels: usize) -> impl Fn(usize, usize) -> C + '_ {
    move |p, l| costs[p * num_labels + l]
}

/// The energy of `labels` (`#sites`, each < L), computed from the callbacks: +∞ costs stay +∞
/// (a zero edge weight cancels them). Errors on size mismatches and NaN costs.
pub fn energy_of<C, D, V>(energy: &MrfEnergy<'_, C, D, V>, labels: &[u32]) -> Result<C>
where
    C: Capacity,
    D: Fn(usize, usize) -> C,
    V: Fn(usize, usize, usize, usize) -> C,
{
    energy.validate()?;
    energy.validate_labels(labels, "labelling")?;
    let mut total = C::ZERO;
    for (p, &l) in labels.iter().enumerate() {
        let v = (energy.unary)(p, l as usize);
        if v.is_nan() || (v.is_infinite() && v < C::ZERO) {
            return Err(Error::NonFiniteCost {
                term: "unary",
                value: format!("{v:?}"),
                location: format!("site {p}, label {l}"),
            });
        }
        total += v;
    }
    for (k, &[p, q]) in energy.edges.iter().enumerate() {
        let (lp, lq) = (labels[p as usize] as usize, labels[q as usize] as usize);
        let v = (energy.pairwise)(p as usize, q as usize, lp, lq);
        if v.is_nan() || (v.is_infinite() && v < C::ZERO) {
            return Err(Error::NonFiniteCost {
                term: "pairwise",
                value: format!("{v:?}"),
                location: format!("edge {k} = [{p}, {q}], labels ({lp}, {lq})"),
            });
        }
        let w = energy.weight(k);
        if w != C::ZERO {
            total += w * v;
        }
    }
    Ok(total)
}

/// The binary term of one edge between two graph nodes of a move, computed in parallel and
/// added to the graph afterwards (the graph itself is built sequentially).
#[derive(Debug, Clone, Copy, Default)]
struct EdgeTerm<C> {
    /// Graph nodes of the edge's ends (`vs` is the edge's first site); `u32::MAX` when the slot
    /// holds no term (the edge was visited from its other end, or leads to a fixed site).
    vs: u32,
    vt: u32,
    /// Arc capacities s→t and t→s.
    cap: C,
    rev_cap: C,
    /// Unary parts for `vs` and `vt`.
    ds: C,
    dt: C,
}

/// Sites per parallel chunk when a move's terms are computed (below about two chunks' worth of
/// variables the move is built on one thread: rayon's fork costs more than it saves).
const TERM_CHUNK: usize = 256;

/// What one expansion move did.
#[derive(Debug, Clone, Copy)]
struct MoveOutcome<C> {
    /// The (clamped) energy after the move, when it lowered the energy.
    accepted: Option<C>,
    /// Truncated (non-submodular) terms in this move.
    truncated: usize,
}

/// Reusable alpha-expansion solver: keeps the max-flow graphs and scratch buffers between moves
/// and between solves (the precompute / solve split for repeated retargeting runs).
///
/// **Parallel moves.** With T rayon threads (T > 1), the next T moves of the schedule are solved
/// at once, each on its own graph, against the same labelling; their outcomes are then taken in
/// schedule order up to the first move that lowers the energy, which is applied, and the moves
/// after it are discarded and solved again from the new labelling. Every move that is used was
/// therefore solved from exactly the labelling the sequential algorithm would have given it, so
/// the result (labels, energy, cycles, move counts) is identical for every thread count; only
/// the time changes. This pays because most moves fail once the labelling is near a local
/// minimum (every move of the final, confirming cycle fails), and costs little otherwise: a
/// discarded move ran on an otherwise idle core. With one thread, moves run one at a time and
/// each move's binary terms are computed in parallel chunks instead.
#[derive(Debug, Clone, Default)]
pub struct AlphaExpansion<C: Capacity> {
    /// Incident edges of each site: `incident[incident_start[p]..incident_start[p + 1]]`.
    incidence: Incidence,
    /// One move's graph and scratch buffers per concurrently solved move.
    workers: Vec<MoveWorker<C>>,
    /// D(p, l) label-major (`l · N + p`), when N · L ≤ [`UNARY_CACHE_MAX`]: a move reads one
    /// label's column in site order instead of striding through the callback's table.
    unary_by_label: Vec<C>,
    /// D(p, x_p) of the current labelling, clamped (+∞ → `infinite_cost`).
    keep_cost: Vec<C>,
    /// Per label α: the graph of α's last move, kept for the next α-move (flow recycling,
    /// integer capacities only); `None` for labels beyond the memory budget.
    recycled: Vec<Option<Recycled<C>>>,
}

/// The move graph of one label kept between its moves, so that the next α-move starts from the
/// last one's flow and search trees (Kohli & Torr, "Efficiently solving dynamic Markov random
/// fields using graph cuts", ICCV 2005; Alahari, Kohli & Torr, "Reduce, reuse & recycle",
/// CVPR 2008). Every site is a node, and every edge a pair of arcs (of zero capacity while an
/// end is labelled α), so the graph's structure never changes; before the next α-move only the
/// terms of the sites whose label changed since, and of their edges, are updated, and the
/// max-flow continues from the previous flow ([`Graph::change_edge_capacity`],
/// [`Graph::maxflow_reuse`]). Near convergence few labels change between two moves of the same
/// label, so most of a move's cost (building its graph, pushing its flow) is saved.
///
/// The move applied is the one the fresh graph gives: the sites the source reaches in the
/// residual graph (and those reaching the sink) are the same for every maximum flow, and the
/// ties are broken on those sets. Integer capacities only: with floating-point ones the
/// recycled flow would carry other rounding than a fresh one.
#[derive(Debug, Clone, Default)]
struct Recycled<C: Capacity> {
    graph: Graph<C>,
    /// The labelling the graph encodes (empty: not built yet).
    labels: Vec<u32>,
    /// Per site: the move's unary coefficient, cost(switch) − cost(keep), with the edges' parts.
    net: Vec<C>,
    /// Σ of the sink capacities, max(0, −net).
    sink_total: C,
    /// Truncated (non-submodular) edge terms in the graph.
    truncated: usize,
}

/// Memory for the kept move graphs of [`Recycled`] (labels past it get a fresh graph per move):
/// 256 MB hold all 64 labels' graphs of the 30³ 6-connected `mrf_grid_v1` benchmark (about
/// 3.6 MB each on 32-bit capacities) and 25 of the 26-connected one's.
const RECYCLE_BUDGET_BYTES: usize = 256 << 20;

/// A kept move graph is rebuilt from scratch, rather than updated, when more than one site in
/// `RECYCLE_REBUILD` changed label since its last move.
const RECYCLE_REBUILD: usize = 4;

/// One edge's part of an α-move over all sites: arcs (zero unless both ends may switch) and the
/// unary parts it adds to its ends.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct SiteEdgeTerm<C> {
    cap: C,
    rev_cap: C,
    us: C,
    ut: C,
    truncated: bool,
}

/// Largest N · L for which the unary costs are cached label-major (64 MB of `i64`).
const UNARY_CACHE_MAX: usize = 1 << 23;

/// Site → incident edges.
#[derive(Debug, Clone, Default)]
struct Incidence {
    start: Vec<u32>,
    list: Vec<u32>,
}

/// Unary costs as the moves read them.
struct UnaryCosts<'a, C> {
    /// D(p, l) at `l · N + p`, when cached.
    by_label: Option<&'a [C]>,
    /// D(p, x_p) of the current labelling, clamped.
    keep: &'a [C],
}

/// The graph and buffers of one expansion move.
#[derive(Debug, Clone, Default)]
struct MoveWorker<C: Capacity> {
    graph: Graph<C>,
    /// Graph node of each site in the current move, or `u32::MAX` for sites already labelled α.
    var_of: Vec<u32>,
    /// Site of each graph node.
    site_of: Vec<u32>,
    /// Accumulated unary coefficient of each graph node: cost(switch) − cost(keep).
    tdelta: Vec<C>,
    /// Sites the move switches to α.
    switched: Vec<u32>,
    /// Per site: switched by the current move.
    is_switched: Vec<bool>,
    /// One slot per entry of the incidence list: the move's binary term of that edge when it
    /// joins two graph nodes and is stored at its first site.
    terms: Vec<EdgeTerm<C>>,
    /// Recycled moves: sites whose label changed since the kept graph's move.
    dirty: Vec<u32>,
    /// Recycled moves: change of each site's unary coefficient (zero between moves) and the
    /// sites with a change.
    net_delta: Vec<C>,
    touched: Vec<u32>,
}

const FIXED: u32 = u32::MAX;

/// One scheduled move as the sequential algorithm sees it.
#[derive(Debug, Clone, Copy)]
struct Step<C> {
    alpha: u32,
    /// Solved by a graph cut (false: skipped, known to fail).
    solved: bool,
    outcome: MoveOutcome<C>,
}

/// Which labels are tried next: the cycle logic of [`CycleStrategy`], fed with the outcome of
/// each move in order. [`Schedule::upcoming`] lists the moves of the current pass in the order
/// they will run if every one of them fails, which is what the parallel moves speculate on.
#[derive(Debug)]
struct Schedule {
    strategy: CycleStrategy,
    order: Vec<u32>,
    rng: Option<rand_chacha::ChaCha8Rng>,
    /// Passes started (cycles).
    passes: usize,
    /// Passes that count against `max_cycles`: every pass, or for Queue those of the outermost
    /// queue.
    counted: usize,
    in_pass: bool,
    // Full / Adaptive sweeps.
    pos: usize,
    improved: bool,
    full_cycle: bool,
    succeeded: Vec<bool>,
    succeeded_now: Vec<bool>,
    // Queue (GCO's strategic expansion): the stack of queue sizes, the next unchecked label and
    // the end of the current pass's queue.
    stack: Vec<usize>,
    next: usize,
    pass_start: usize,
    queue_end: usize,
}

impl Schedule {
    fn new(options: &AlphaExpansionOptions, num_labels: usize) -> Schedule {
        let mut order: Vec<u32> = (0..num_labels as u32).collect();
        let mut rng = match options.label_order {
            LabelOrder::Random { seed } => Some(rand_chacha::ChaCha8Rng::seed_from_u64(seed)),
            LabelOrder::Sequential => None,
        };
        if options.cycles == CycleStrategy::Queue {
            // GCO permutes the label table once per solve.
            if let Some(rng) = rng.as_mut() {
                order.shuffle(rng);
            }
        }
        Schedule {
            strategy: options.cycles,
            order,
            rng,
            passes: 0,
            counted: 0,
            in_pass: false,
            pos: 0,
            improved: false,
            full_cycle: true,
            succeeded: vec![true; num_labels],
            succeeded_now: vec![false; num_labels],
            stack: vec![num_labels],
            next: 0,
            pass_start: 0,
            queue_end: 0,
        }
    }

    /// Starts a pass if none is running. Returns false when the schedule is finished.
    fn begin_pass(&mut self, max_passes: usize) -> bool {
        if self.in_pass {
            return true;
        }
        let counts = self.strategy != CycleStrategy::Queue || self.stack.len() == 1;
        if counts && self.counted >= max_passes {
            return false;
        }
        match self.strategy {
            CycleStrategy::Full | CycleStrategy::Adaptive => {
                if let Some(rng) = self.rng.as_mut() {
                    self.order.shuffle(rng);
                }
                self.pos = 0;
                self.improved = false;
                self.succeeded_now.fill(false);
            }
            CycleStrategy::Queue => {
                let Some(&end) = self.stack.last() else { return false };
                self.queue_end = end;
                self.pass_start = self.next;
            }
        }
        self.passes += 1;
        self.counted += usize::from(counts);
        self.in_pass = true;
        true
    }

    /// The remaining moves of the current pass, in the order they run if all of them fail, and
    /// whether each one is skipped by the cycle rule (not by the solver's own knowledge).
    fn upcoming(&self, out: &mut Vec<(u32, bool)>) {
        out.clear();
        match self.strategy {
            CycleStrategy::Full | CycleStrategy::Adaptive => {
                for &a in &self.order[self.pos..] {
                    out.push((a, !self.full_cycle && !self.succeeded[a as usize]));
                }
            }
            CycleStrategy::Queue => {
                // A failing label is swapped with the last unchecked one, which runs next.
                if self.next < self.queue_end {
                    out.push((self.order[self.next], false));
                    for i in (self.next + 1..self.queue_end).rev() {
                        out.push((self.order[i], false));
                    }
                }
            }
        }
    }

    /// Records the outcome of the next move of the pass. Returns true when the pass ended.
    fn record(&mut self, alpha: u32, success: bool) -> bool {
        match self.strategy {
            CycleStrategy::Full | CycleStrategy::Adaptive => {
                debug_assert_eq!(self.order[self.pos], alpha);
                self.pos += 1;
                if success {
                    self.improved = true;
                    self.succeeded_now[alpha as usize] = true;
                }
                self.pos == self.order.len()
            }
            CycleStrategy::Queue => {
                debug_assert_eq!(self.order[self.next], alpha);
                if success {
                    self.next += 1;
                } else {
                    self.queue_end -= 1;
                    self.order.swap(self.next, self.queue_end);
                }
                self.next >= self.queue_end
            }
        }
    }

    /// Closes the pass that just ended. Returns true when the labelling is known to be a local
    /// minimum of every expansion move (the schedule is finished).
    fn end_pass(&mut self) -> bool {
        self.in_pass = false;
        match self.strategy {
            CycleStrategy::Full | CycleStrategy::Adaptive => {
                if !self.improved {
                    if !self.full_cycle {
                        self.full_cycle = true;
                        return false;
                    }
                    return true;
                }
                self.full_cycle = self.strategy == CycleStrategy::Full;
                std::mem::swap(&mut self.succeeded, &mut self.succeeded_now);
                false
            }
            CycleStrategy::Queue => {
                let top = *self.stack.last().expect("a pass runs on a queue");
                if self.next == self.pass_start {
                    // Nothing succeeded: go back to the unchecked labels of the enclosing queue.
                    self.next = top;
                    self.stack.pop();
                } else {
                    if self.queue_end < top / 2 {
                        // Few succeeded: focus on them in a new, smaller queue.
                        self.stack.push(self.queue_end);
                    }
                    self.next = 0;
                }
                self.stack.is_empty()
            }
        }
    }
}

impl<C: Capacity> AlphaExpansion<C> {
    /// An empty solver; buffers grow on the first solve.
    pub fn new() -> Self {
        AlphaExpansion {
            incidence: Incidence::default(),
            workers: Vec::new(),
            unary_by_label: Vec::new(),
            keep_cost: Vec::new(),
            recycled: Vec::new(),
        }
    }

    /// Runs alpha-expansion from `init` (`#sites` labels, each < L).
    ///
    /// # Errors
    /// [`Error::InvalidEnergy`] for malformed energies or initial labels,
    /// [`Error::NonFiniteCost`] when a callback returns NaN or −∞.
    pub fn solve<D, V>(
        &mut self,
        energy: &MrfEnergy<'_, C, D, V>,
        init: &[u32],
        options: &AlphaExpansionOptions,
    ) -> Result<AlphaExpansionResult<C>>
    where
        D: Fn(usize, usize) -> C + Sync,
        V: Fn(usize, usize, usize, usize) -> C + Sync,
    {
        let start = Instant::now();
        energy.validate()?;
        energy.validate_labels(init, "initial labelling")?;
        if options.infinite_cost.is_nan() || options.infinite_cost <= 0.0 {
            return Err(Error::energy(format!(
                "infinite_cost must be a positive number, got {}",
                options.infinite_cost
            )));
        }
        let hard = C::from_f64(options.infinite_cost);
        let num_labels = energy.num_labels;
        let initial_energy = energy_of(energy, init)?;
        self.incidence.build(energy.num_sites, energy.edges);
        let threads = rayon::current_num_threads().clamp(1, num_labels.max(1));
        if self.workers.len() < threads {
            self.workers.resize_with(threads, MoveWorker::default);
        }
        let mut labels = init.to_vec();
        let mut current = energy.energy_clamped(&labels, hard)?;
        let n = energy.num_sites;
        self.keep_cost.clear();
        for (p, &l) in labels.iter().enumerate() {
            self.keep_cost.push(energy.unary_clamped(p, l as usize, hard)?);
        }
        self.unary_by_label.clear();
        if n.saturating_mul(num_labels) <= UNARY_CACHE_MAX {
            self.unary_by_label.reserve(n * num_labels);
            for l in 0..num_labels {
                self.unary_by_label.extend((0..n).map(|p| (energy.unary)(p, l)));
            }
        }
        // Kept move graphs (flow recycling) for as many labels as the budget holds.
        self.recycled.clear();
        if !C::IS_FLOAT && options.recycle_flows {
            let per_label = Graph::<C>::bytes_for(n, energy.edges.len()) + n * (4 + std::mem::size_of::<C>());
            let kept = (RECYCLE_BUDGET_BYTES / per_label.max(1)).min(num_labels);
            self.recycled.resize_with(num_labels, || None);
            for slot in &mut self.recycled[..kept] {
                *slot = Some(Recycled::default());
            }
        }

        let mut schedule = Schedule::new(options, num_labels);
        // `known_optimal[α] == Some(k)`: the α-move was optimal (failed, or just succeeded
        // without truncation) when `k` moves had been accepted; while no other move is accepted
        // it cannot lower the energy, so it is skipped.
        let mut known_optimal: Vec<Option<usize>> = vec![None; num_labels];
        let mut cycle_energies = Vec::new();
        let (mut moves, mut accepted_moves, mut truncated_terms) = (0, 0, 0);
        let mut termination = Termination::MaxCycles;
        let mut upcoming = Vec::new();
        let mut steps = Vec::new();
        // Right after a successful move the next one often succeeds too: speculate only once a
        // move has failed (the first move after a success runs alone, with parallel terms).
        let mut after_success = true;
        while schedule.begin_pass(options.max_cycles) {
            schedule.upcoming(&mut upcoming);
            let skip =
                |alpha: u32, by_rule: bool| by_rule || known_optimal[alpha as usize] == Some(accepted_moves);
            let accepted_by = self.first_accepted(
                energy,
                &labels,
                &upcoming,
                &skip,
                current,
                hard,
                options.ties,
                if after_success { 1 } else { threads },
                threads,
                &mut steps,
            )?;
            after_success = accepted_by.is_some();
            let mut pass_ended = false;
            for step in &steps {
                if step.solved {
                    moves += 1;
                }
                truncated_terms += step.outcome.truncated;
                let success = step.outcome.accepted.is_some();
                match step.outcome.accepted {
                    Some(e) => {
                        current = e;
                        accepted_moves += 1;
                        known_optimal[step.alpha as usize] =
                            if step.outcome.truncated == 0 { Some(accepted_moves) } else { None };
                    }
                    None if step.solved => known_optimal[step.alpha as usize] = Some(accepted_moves),
                    None => {}
                }
                pass_ended = schedule.record(step.alpha, success);
            }
            if let (Some(w), Some(step)) = (accepted_by, steps.last()) {
                for &p in &self.workers[w].switched {
                    labels[p as usize] = step.alpha;
                    self.keep_cost[p as usize] =
                        energy.unary_clamped(p as usize, step.alpha as usize, hard)?;
                }
            }
            if pass_ended || upcoming.is_empty() {
                cycle_energies.push(current);
                if schedule.end_pass() {
                    termination = Termination::Converged;
                    break;
                }
            }
        }
        let final_energy = energy_of(energy, &labels)?;
        Ok(AlphaExpansionResult {
            labels,
            energy: final_energy,
            initial_energy,
            cycles: schedule.passes,
            cycle_energies,
            moves,
            accepted_moves,
            truncated_terms,
            termination,
            elapsed_ms: start.elapsed().as_secs_f64() * 1e3,
            recycled_labels: self.recycled.iter().filter(|r| r.is_some()).count(),
        })
    }

    /// Runs the moves of `upcoming` in order until one lowers the energy: `first_width` at first,
    /// then `threads` at a time.
    /// Fills `steps` with the moves up to and including that one (all of them when none does)
    /// and returns the worker that holds the accepted move's switched sites.
    #[allow(clippy::too_many_arguments)]
    fn first_accepted<D, V>(
        &mut self,
        energy: &MrfEnergy<'_, C, D, V>,
        labels: &[u32],
        upcoming: &[(u32, bool)],
        skip: &impl Fn(u32, bool) -> bool,
        current: C,
        hard: C,
        ties: TieBreak,
        first_width: usize,
        threads: usize,
        steps: &mut Vec<Step<C>>,
    ) -> Result<Option<usize>>
    where
        D: Fn(usize, usize) -> C + Sync,
        V: Fn(usize, usize, usize, usize) -> C + Sync,
    {
        steps.clear();
        let incidence = &self.incidence;
        let costs = UnaryCosts {
            by_label: (!self.unary_by_label.is_empty()).then_some(&self.unary_by_label[..]),
            keep: &self.keep_cost,
        };
        let mut i = 0;
        let mut width = first_width.clamp(1, threads);
        let mut batch: Vec<(usize, u32)> = Vec::with_capacity(threads);
        while i < upcoming.len() {
            // The next `threads` moves that are not skipped.
            batch.clear();
            let mut j = i;
            while j < upcoming.len() && batch.len() < width {
                let (alpha, by_rule) = upcoming[j];
                if !skip(alpha, by_rule) {
                    batch.push((j, alpha));
                }
                j += 1;
            }
            // The batch's kept graphs, taken out of their slots while their moves run.
            let mut kept: Vec<Option<Recycled<C>>> = batch
                .iter()
                .map(|&(_, alpha)| self.recycled.get_mut(alpha as usize).and_then(Option::take))
                .collect();
            let run = |w: &mut MoveWorker<C>, rec: &mut Option<Recycled<C>>, alpha: u32, parallel: bool| {
                match rec {
                    Some(rec) => {
                        w.expand_recycled(rec, energy, incidence, labels, alpha, current, hard, ties)
                    }
                    None => w.expand(energy, incidence, &costs, labels, alpha, current, hard, ties, parallel),
                }
            };
            let outcomes: Vec<Result<MoveOutcome<C>>> = if batch.len() <= 1 {
                batch
                    .iter()
                    .zip(kept.iter_mut())
                    .map(|(&(_, alpha), rec)| run(&mut self.workers[0], rec, alpha, true))
                    .collect()
            } else {
                self.workers[..batch.len()]
                    .par_iter_mut()
                    .zip(kept.par_iter_mut())
                    .zip(batch.par_iter())
                    .map(|((w, rec), &(_, alpha))| run(w, rec, alpha, false))
                    .collect()
            };
            for (&(_, alpha), rec) in batch.iter().zip(kept) {
                if rec.is_some() {
                    self.recycled[alpha as usize] = rec;
                }
            }
            let mut outcomes = outcomes.into_iter();
            let mut b = 0;
            for k in i..j {
                let (alpha, by_rule) = upcoming[k];
                if b < batch.len() && batch[b].0 == k {
                    let outcome = outcomes.next().expect("one outcome per solved move")?;
                    steps.push(Step { alpha, solved: true, outcome });
                    if outcome.accepted.is_some() {
                        return Ok(Some(b));
                    }
                    b += 1;
                } else {
                    debug_assert!(skip(alpha, by_rule));
                    steps.push(Step {
                        alpha,
                        solved: false,
                        outcome: MoveOutcome { accepted: None, truncated: 0 },
                    });
                }
            }
            i = j;
            width = threads;
        }
        Ok(None)
    }
}

impl Incidence {
    /// Site → incident edges, for building moves and scoring their energy change.
    fn build(&mut self, num_sites: usize, edges: &[[u32; 2]]) {
        self.start.clear();
        self.start.resize(num_sites + 1, 0);
        for &[p, q] in edges {
            self.start[p as usize + 1] += 1;
            self.start[q as usize + 1] += 1;
        }
        for p in 0..num_sites {
            self.start[p + 1] += self.start[p];
        }
        self.list.clear();
        self.list.resize(2 * edges.len(), 0);
        // Fill from the back so each site's list ends up in edge order.
        let mut fill = self.start[1..].to_vec();
        for (k, &[p, q]) in edges.iter().enumerate().rev() {
            for s in [p as usize, q as usize] {
                fill[s] -= 1;
                self.list[fill[s] as usize] = k as u32;
            }
        }
    }

    #[inline]
    fn of(&self, p: usize) -> &[u32] {
        &self.list[self.start[p] as usize..self.start[p + 1] as usize]
    }
}

impl<C: Capacity> MoveWorker<C> {
    /// One α-expansion move from `labels` (energy `current`, clamped). When it lowers the energy,
    /// returns the new energy and leaves the sites to switch in `self.switched`; `labels` is not
    /// changed. Among the optimal moves, `ties` picks the one switching the most or the fewest
    /// sites to α.
    ///
    /// Only sites that can switch become graph nodes: sites already labelled α and sites where
    /// D(α) = +∞ (α forbidden) keep their labels, and only the edges at switchable sites are
    /// visited. The move's energy is `current + flow − Σ sink capacities` (the all-keep cut
    /// costs exactly the sink capacities and has energy `current`), or the exact energy change
    /// when that is inaccurate.
    #[allow(clippy::too_many_arguments)]
    fn expand<D, V>(
        &mut self,
        energy: &MrfEnergy<'_, C, D, V>,
        incidence: &Incidence,
        costs: &UnaryCosts<'_, C>,
        labels: &[u32],
        alpha: u32,
        current: C,
        hard: C,
        ties: TieBreak,
        parallel_terms: bool,
    ) -> Result<MoveOutcome<C>>
    where
        D: Fn(usize, usize) -> C + Sync,
        V: Fn(usize, usize, usize, usize) -> C + Sync,
    {
        let a = alpha as usize;
        let n = energy.num_sites;
        self.var_of.clear();
        self.var_of.resize(n, FIXED);
        self.site_of.clear();
        self.tdelta.clear();
        let column = costs.by_label.map(|c| &c[a * n..(a + 1) * n]);
        for (p, &l) in labels.iter().enumerate() {
            if l == alpha {
                continue;
            }
            let switch = match column {
                Some(c) => c[p],
                None => (energy.unary)(p, a),
            };
            if switch.is_infinite() && switch > C::ZERO {
                continue; // α is forbidden at p
            }
            if switch.is_nan() || switch.is_infinite() {
                return Err(Error::NonFiniteCost {
                    term: "unary",
                    value: format!("{switch:?}"),
                    location: format!("site {p}, label {a}"),
                });
            }
            let keep = costs.keep[p];
            self.var_of[p] = self.site_of.len() as u32;
            self.site_of.push(p as u32);
            self.tdelta.push(switch - keep);
        }
        let num_vars = self.site_of.len();
        if num_vars == 0 {
            return Ok(MoveOutcome { accepted: None, truncated: 0 });
        }
        // The binary terms of the move (per site chunk in parallel when asked: each chunk writes
        // its own sites' `tdelta` and `terms` slots), then added to the graph in site order.
        let truncated = self.compute_terms(energy, incidence, labels, alpha, hard, parallel_terms)?;
        self.graph.reset(num_vars);
        for v in 0..num_vars {
            let p = self.site_of[v] as usize;
            for i in incidence.start[p] as usize..incidence.start[p + 1] as usize {
                let t = self.terms[i];
                if t.vs == u32::MAX {
                    continue;
                }
                let (vs, vt) = (t.vs as usize, t.vt as usize);
                self.tdelta[vs] += t.ds;
                self.tdelta[vt] += t.dt;
                if t.cap > C::ZERO || t.rev_cap > C::ZERO {
                    self.graph.add_edge(vs, vt, t.cap, t.rev_cap);
                }
            }
        }
        // y = 1 (sink side) cuts the source link: cost(switch) − cost(keep) = d.
        let mut sink_total = C::ZERO;
        for v in 0..num_vars {
            let d = self.tdelta[v];
            if d > C::ZERO {
                self.graph.add_tweights(v, d, C::ZERO);
            } else if d < C::ZERO {
                self.graph.add_tweights(v, C::ZERO, -d);
                sink_total -= d;
            }
        }
        let flow = self.graph.maxflow();

        // Sink side = switch to α. Every node the source cannot reach is on the sink side of a
        // minimum cut, and so is every node that reaches the sink; the nodes in neither set
        // (free) are ties.
        let free_to = ties.free_side();
        self.switched.clear();
        for (v, &p) in self.site_of.iter().enumerate() {
            if self.graph.what_segment_or(v, free_to) == Segment::Sink {
                self.switched.push(p);
            }
        }
        if self.switched.is_empty() {
            return Ok(MoveOutcome { accepted: None, truncated });
        }
        let new_energy = if truncated == 0 && flow_is_accurate(sink_total, flow, current) {
            current + flow - sink_total
        } else {
            // The cut minimised an upper bound (truncation), or the flow is far larger than the
            // energy (with floats, +∞ costs replaced by `infinite_cost` flow through the graph,
            // leaving rounding errors): score the move by its exact energy change instead.
            current + self.energy_change(energy, incidence, labels, alpha, hard)?
        };
        if !lower(new_energy, current) {
            return Ok(MoveOutcome { accepted: None, truncated });
        }
        Ok(MoveOutcome { accepted: Some(new_energy), truncated })
    }

    /// One α-move on the label's kept graph (see [`Recycled`]): the graph is brought up to
    /// `labels` (rebuilt when it is new or many labels changed), its max-flow continued, and the
    /// outcome read as in [`MoveWorker::expand`], whose result it equals.
    #[allow(clippy::too_many_arguments)]
    fn expand_recycled<D, V>(
        &mut self,
        rec: &mut Recycled<C>,
        energy: &MrfEnergy<'_, C, D, V>,
        incidence: &Incidence,
        labels: &[u32],
        alpha: u32,
        current: C,
        hard: C,
        ties: TieBreak,
    ) -> Result<MoveOutcome<C>>
    where
        D: Fn(usize, usize) -> C + Sync,
        V: Fn(usize, usize, usize, usize) -> C + Sync,
    {
        debug_assert!(!C::IS_FLOAT, "recycled moves need exact (integer) capacities");
        let n = energy.num_sites;
        self.dirty.clear();
        if rec.labels.len() == n {
            self.dirty.extend((0..n as u32).filter(|&p| rec.labels[p as usize] != labels[p as usize]));
        }
        let rebuild = rec.labels.len() != n || self.dirty.len() * RECYCLE_REBUILD > n;
        let built = if rebuild {
            rebuild_recycled(rec, energy, labels, alpha, hard)
        } else {
            self.update_recycled(rec, energy, incidence, labels, alpha, hard)
        };
        if let Err(e) = built {
            // A graph half brought up to date is rebuilt next time.
            rec.labels.clear();
            return Err(e);
        }
        if rebuild {
            rec.graph.maxflow();
            rec.graph.release_build_buffers();
        } else {
            rec.graph.maxflow_reuse();
        }
        let free_to = ties.free_side();
        self.switched.clear();
        for (p, &l) in labels.iter().enumerate() {
            if l != alpha && rec.graph.what_segment_or(p, free_to) == Segment::Sink {
                self.switched.push(p as u32);
            }
        }
        let truncated = rec.truncated;
        if self.switched.is_empty() {
            return Ok(MoveOutcome { accepted: None, truncated });
        }
        let new_energy = if truncated == 0 {
            current + rec.graph.flow() - rec.sink_total
        } else {
            current + self.energy_change(energy, incidence, labels, alpha, hard)?
        };
        if !lower(new_energy, current) {
            return Ok(MoveOutcome { accepted: None, truncated });
        }
        Ok(MoveOutcome { accepted: Some(new_energy), truncated })
    }

    /// Brings a kept graph from its labelling to `labels`, whose changed sites are
    /// `self.dirty`: the unary parts of those sites and the terms of their edges change by the
    /// difference of their values under the two labellings.
    fn update_recycled<D, V>(
        &mut self,
        rec: &mut Recycled<C>,
        energy: &MrfEnergy<'_, C, D, V>,
        incidence: &Incidence,
        labels: &[u32],
        alpha: u32,
        hard: C,
    ) -> Result<()>
    where
        D: Fn(usize, usize) -> C,
        V: Fn(usize, usize, usize, usize) -> C,
    {
        let n = energy.num_sites;
        if self.net_delta.len() != n {
            self.net_delta.clear();
            self.net_delta.resize(n, C::ZERO);
        } else {
            // Zero again what an update stopped by an error left behind.
            for &p in &self.touched {
                self.net_delta[p as usize] = C::ZERO;
            }
        }
        self.touched.clear();
        let (delta, touched) = (&mut self.net_delta, &mut self.touched);
        let mut add = |p: usize, d: C| {
            if d != C::ZERO {
                if delta[p] == C::ZERO {
                    touched.push(p as u32);
                }
                delta[p] += d;
            }
        };
        let old = &rec.labels;
        for &p in &self.dirty {
            let p = p as usize;
            add(
                p,
                site_unary(energy, p, labels[p], alpha, hard)? - site_unary(energy, p, old[p], alpha, hard)?,
            );
            for &k in incidence.of(p) {
                let k = k as usize;
                let [s, t] = energy.edges[k];
                let other = if s as usize == p { t as usize } else { s as usize };
                if other < p && old[other] != labels[other] {
                    continue; // updated from the other end
                }
                let before = edge_term(energy, k, old, alpha, hard)?;
                let after = edge_term(energy, k, labels, alpha, hard)?;
                if before == after {
                    continue;
                }
                if before.cap != after.cap || before.rev_cap != after.rev_cap {
                    let arc = rec.graph.arc_of_edge(k);
                    rec.graph.change_edge_capacity(
                        arc,
                        after.cap - before.cap,
                        after.rev_cap - before.rev_cap,
                    );
                }
                add(s as usize, after.us - before.us);
                add(t as usize, after.ut - before.ut);
                rec.truncated = rec.truncated + usize::from(after.truncated) - usize::from(before.truncated);
            }
        }
        for &p in &self.touched {
            let p = p as usize;
            let d = std::mem::replace(&mut self.net_delta[p], C::ZERO);
            if d == C::ZERO {
                continue;
            }
            let (before, after) = (rec.net[p], rec.net[p] + d);
            rec.graph.add_tweights(p, pos(after) - pos(before), pos(-after) - pos(-before));
            rec.sink_total += pos(-after) - pos(-before);
            rec.net[p] = after;
        }
        for &p in &self.dirty {
            rec.labels[p as usize] = labels[p as usize];
        }
        Ok(())
    }

    /// Fills `self.terms` (and adds the fixed-neighbour parts to `self.tdelta`) for an
    /// α-expansion move whose graph nodes are `self.site_of` / `self.var_of`. Returns the number
    /// of truncated (non-submodular) terms.
    ///
    /// E(y_s, y_t), y = 1 meaning "switch to α": A = E(0,0), B = E(0,1), C = E(1,0), D = E(1,1).
    /// With K = B + C − A − D ≥ 0 split into arcs s→t (cut when y_s = 0, y_t = 1) of capacity
    /// K − e and t→s of capacity e: E = A + (C − A − e) y_s + (D − C + e) y_t + cuts. Any
    /// e ∈ [0, K] is exact; e = clamp(C − A, 0, K) zeroes one unary part, so a term that only
    /// penalises disagreement (A = D = 0, B = C) costs arcs both ways and no terminal flow (the
    /// one-sided split would route K through the terminals).
    fn compute_terms<D, V>(
        &mut self,
        energy: &MrfEnergy<'_, C, D, V>,
        incidence: &Incidence,
        labels: &[u32],
        alpha: u32,
        hard: C,
        parallel: bool,
    ) -> Result<usize>
    where
        D: Fn(usize, usize) -> C + Sync,
        V: Fn(usize, usize, usize, usize) -> C + Sync,
    {
        let a = alpha as usize;
        let n = energy.num_sites;
        self.terms.clear();
        self.terms.resize(incidence.list.len(), EdgeTerm { vs: u32::MAX, ..Default::default() });
        let var_of = &self.var_of;
        let incident = &incidence.list;
        let incident_start = &incidence.start;
        // One chunk of sites: its variables are contiguous (numbered in site order), and so are
        // its `terms` slots.
        let chunk = |p0: usize, terms: &mut [EdgeTerm<C>], tdelta: &mut [C]| -> Result<usize> {
            let base = incident_start[p0] as usize;
            let p1 = (p0 + TERM_CHUNK).min(n);
            let v0 = (p0..p1).map(|p| var_of[p]).find(|&v| v != FIXED).unwrap_or(0) as usize;
            let mut truncated = 0;
            for p in p0..p1 {
                let v = var_of[p];
                if v == FIXED {
                    continue;
                }
                let v = v as usize;
                for i in incident_start[p] as usize..incident_start[p + 1] as usize {
                    let k = incident[i] as usize;
                    let [s, t] = energy.edges[k];
                    let (s, t) = (s as usize, t as usize);
                    let other = if s == p { t } else { s };
                    let vo = var_of[other];
                    let (ls, lt) = (labels[s] as usize, labels[t] as usize);
                    if vo == FIXED {
                        // The other end keeps its label: a unary term of p.
                        let keep = energy.pairwise_clamped(k, s, t, ls, lt, hard)?;
                        let switch = if s == p {
                            energy.pairwise_clamped(k, s, t, a, lt, hard)?
                        } else {
                            energy.pairwise_clamped(k, s, t, ls, a, hard)?
                        };
                        tdelta[v - v0] += switch - keep;
                        continue;
                    }
                    if other < p {
                        continue; // stored at the other end
                    }
                    let (vs, vt) = if s == p { (v, vo as usize) } else { (vo as usize, v) };
                    let term = binary_term(energy, k, ls, lt, a, hard)?;
                    truncated += usize::from(term.truncated);
                    terms[i - base] = EdgeTerm {
                        vs: vs as u32,
                        vt: vt as u32,
                        cap: term.cap,
                        rev_cap: term.rev_cap,
                        ds: term.us,
                        dt: term.ut,
                    };
                }
            }
            Ok(truncated)
        };
        if !parallel || self.site_of.len() < 2 * TERM_CHUNK {
            return chunk_all(n, &mut self.terms, &mut self.tdelta, incident_start, var_of, &chunk);
        }
        // Split `terms` and `tdelta` at the chunk boundaries.
        let mut pieces = Vec::with_capacity(n.div_ceil(TERM_CHUNK));
        let (mut terms, mut tdelta): (&mut [EdgeTerm<C>], &mut [C]) = (&mut self.terms, &mut self.tdelta);
        let mut vars_before = 0usize;
        for p0 in (0..n).step_by(TERM_CHUNK) {
            let p1 = (p0 + TERM_CHUNK).min(n);
            let edges_here = (incident_start[p1] - incident_start[p0]) as usize;
            let vars_here = (p0..p1).filter(|&p| var_of[p] != FIXED).count();
            let (t_here, t_rest) = std::mem::take(&mut terms).split_at_mut(edges_here);
            let (d_here, d_rest) = std::mem::take(&mut tdelta).split_at_mut(vars_here);
            terms = t_rest;
            tdelta = d_rest;
            vars_before += vars_here;
            pieces.push((p0, t_here, d_here));
        }
        debug_assert_eq!(vars_before, self.site_of.len());
        pieces.into_par_iter().map(|(p0, t, d)| chunk(p0, t, d)).try_reduce(|| 0, |x, y| Ok(x + y))
    }

    /// E(after) − E(before) of switching `self.switched` to `alpha`, summed over the terms that
    /// change (unary terms of the switched sites, pairwise terms of their edges).
    fn energy_change<D, V>(
        &mut self,
        energy: &MrfEnergy<'_, C, D, V>,
        incidence: &Incidence,
        labels: &[u32],
        alpha: u32,
        hard: C,
    ) -> Result<C>
    where
        D: Fn(usize, usize) -> C,
        V: Fn(usize, usize, usize, usize) -> C,
    {
        self.is_switched.clear();
        self.is_switched.resize(labels.len(), false);
        for &p in &self.switched {
            self.is_switched[p as usize] = true;
        }
        let after = |s: usize| if self.is_switched[s] { alpha as usize } else { labels[s] as usize };
        let mut delta = C::ZERO;
        for &p in &self.switched {
            let p = p as usize;
            delta += energy.unary_clamped(p, alpha as usize, hard)?
                - energy.unary_clamped(p, labels[p] as usize, hard)?;
            for &k in incidence.of(p) {
                let [s, t] = energy.edges[k as usize];
                let (s, t) = (s as usize, t as usize);
                let other = if s == p { t } else { s };
                if self.is_switched[other] && other < p {
                    continue; // counted from the other end
                }
                delta += energy.pairwise_clamped(k as usize, s, t, after(s), after(t), hard)?
                    - energy.pairwise_clamped(
                        k as usize,
                        s,
                        t,
                        labels[s] as usize,
                        labels[t] as usize,
                        hard,
                    )?;
            }
        }
        Ok(delta)
    }
}

/// `max(x, 0)`.
#[inline]
fn pos<C: Capacity>(x: C) -> C {
    if x > C::ZERO { x } else { C::ZERO }
}

/// A site's own part of an α-move over all sites: D(p, α) − D(p, x_p), or 0 when x_p = α.
#[inline]
fn site_unary<C, D, V>(
    energy: &MrfEnergy<'_, C, D, V>,
    p: usize,
    label: u32,
    alpha: u32,
    hard: C,
) -> Result<C>
where
    C: Capacity,
    D: Fn(usize, usize) -> C,
    V: Fn(usize, usize, usize, usize) -> C,
{
    if label == alpha {
        return Ok(C::ZERO);
    }
    Ok(energy.unary_clamped(p, alpha as usize, hard)? - energy.unary_clamped(p, label as usize, hard)?)
}

/// Edge `k`'s part of an α-move from `labels` over all sites, split as in
/// [`MoveWorker::compute_terms`] (the same arcs and unary parts when both ends may switch; a
/// unary part of the end that may switch when the other is labelled α; nothing when neither).
fn edge_term<C, D, V>(
    energy: &MrfEnergy<'_, C, D, V>,
    k: usize,
    labels: &[u32],
    alpha: u32,
    hard: C,
) -> Result<SiteEdgeTerm<C>>
where
    C: Capacity,
    D: Fn(usize, usize) -> C,
    V: Fn(usize, usize, usize, usize) -> C,
{
    let a = alpha as usize;
    let [s, t] = energy.edges[k];
    let (s, t) = (s as usize, t as usize);
    let (ls, lt) = (labels[s] as usize, labels[t] as usize);
    let mut term = SiteEdgeTerm::default();
    match (ls != a, lt != a) {
        (false, false) => {}
        (true, false) => {
            term.us = energy.pairwise_clamped(k, s, t, a, lt, hard)?
                - energy.pairwise_clamped(k, s, t, ls, lt, hard)?;
        }
        (false, true) => {
            term.ut = energy.pairwise_clamped(k, s, t, ls, a, hard)?
                - energy.pairwise_clamped(k, s, t, ls, lt, hard)?;
        }
        (true, true) => term = binary_term(energy, k, ls, lt, a, hard)?,
    }
    Ok(term)
}

/// The move's binary term of edge `k` = [s, t] between two sites that may both switch (labels
/// `ls`, `lt`; α = `a`), split into arcs and unary parts as [`MoveWorker::compute_terms`]
/// documents: truncated (B raised to A + D − C) when not submodular.
#[inline]
fn binary_term<C, D, V>(
    energy: &MrfEnergy<'_, C, D, V>,
    k: usize,
    ls: usize,
    lt: usize,
    a: usize,
    hard: C,
) -> Result<SiteEdgeTerm<C>>
where
    C: Capacity,
    D: Fn(usize, usize) -> C,
    V: Fn(usize, usize, usize, usize) -> C,
{
    let [s, t] = energy.edges[k];
    let (s, t) = (s as usize, t as usize);
    let ea = energy.pairwise_clamped(k, s, t, ls, lt, hard)?;
    let mut eb = energy.pairwise_clamped(k, s, t, ls, a, hard)?;
    let ec = energy.pairwise_clamped(k, s, t, a, lt, hard)?;
    let ed = energy.pairwise_clamped(k, s, t, a, a, hard)?;
    let truncated = ea + ed > eb + ec;
    if truncated {
        // Not submodular: raise B to A + D − C (an upper bound, exact at the current labelling).
        eb = ea + ed - ec;
    }
    let k_total = eb + ec - ea - ed;
    let mut e = ec - ea;
    if e < C::ZERO {
        e = C::ZERO;
    } else if e > k_total {
        e = k_total;
    }
    let (cap, rev_cap) = if k_total > C::ZERO { (k_total - e, e) } else { (C::ZERO, C::ZERO) };
    Ok(SiteEdgeTerm { cap, rev_cap, us: ec - ea - e, ut: ed - ec + e, truncated })
}

/// Builds a kept move graph from scratch for `labels` (every site a node, every edge a pair of
/// arcs).
fn rebuild_recycled<C, D, V>(
    rec: &mut Recycled<C>,
    energy: &MrfEnergy<'_, C, D, V>,
    labels: &[u32],
    alpha: u32,
    hard: C,
) -> Result<()>
where
    C: Capacity,
    D: Fn(usize, usize) -> C,
    V: Fn(usize, usize, usize, usize) -> C,
{
    let n = energy.num_sites;
    rec.graph.reset(n);
    rec.net.clear();
    for (p, &l) in labels.iter().enumerate() {
        rec.net.push(site_unary(energy, p, l, alpha, hard)?);
    }
    rec.truncated = 0;
    for k in 0..energy.edges.len() {
        let term = edge_term(energy, k, labels, alpha, hard)?;
        let [s, t] = energy.edges[k];
        rec.graph.add_edge(s as usize, t as usize, term.cap, term.rev_cap);
        rec.net[s as usize] += term.us;
        rec.net[t as usize] += term.ut;
        rec.truncated += usize::from(term.truncated);
    }
    rec.sink_total = C::ZERO;
    for p in 0..n {
        let d = rec.net[p];
        rec.graph.add_tweights(p, pos(d), pos(-d));
        rec.sink_total += pos(-d);
    }
    rec.labels.clear();
    rec.labels.extend_from_slice(labels);
    Ok(())
}

/// Runs a move's term `chunk` over every site chunk in turn, on the calling thread.
fn chunk_all<C: Capacity>(
    n: usize,
    terms: &mut [EdgeTerm<C>],
    tdelta: &mut [C],
    incident_start: &[u32],
    var_of: &[u32],
    chunk: &impl Fn(usize, &mut [EdgeTerm<C>], &mut [C]) -> Result<usize>,
) -> Result<usize> {
    let mut truncated = 0;
    let (mut e0, mut v0) = (0usize, 0usize);
    for p0 in (0..n).step_by(TERM_CHUNK) {
        let p1 = (p0 + TERM_CHUNK).min(n);
        let e1 = incident_start[p1] as usize;
        let v1 = v0 + (p0..p1).filter(|&p| var_of[p] != FIXED).count();
        truncated += chunk(p0, &mut terms[e0..e1], &mut tdelta[v0..v1])?;
        (e0, v0) = (e1, v1);
    }
    Ok(truncated)
}

/// Whether `current + flow − sink_total` gives the move's energy accurately: always for integers;
/// for floats when the flow and sink capacities are at most 1000 times the energy, so that the
/// flow's rounding (about one ulp per augmentation) stays far below the acceptance tolerance of
/// [`lower`].
#[inline]
fn flow_is_accurate<C: Capacity>(sink_total: C, flow: C, current: C) -> bool {
    if !C::IS_FLOAT {
        return true;
    }
    let scale = current.to_f64().abs().max(1.0);
    sink_total.to_f64().abs() + flow.to_f64().abs() <= 1e3 * scale
}

/// `new < current`, with a relative tolerance of 1e-10 for floating-point energies (the flow
/// value accumulates rounding over the augmentations; a smaller gain is not worth a move).
#[inline]
fn lower<C: Capacity>(new: C, current: C) -> bool {
    if C::IS_FLOAT {
        let (n, c) = (new.to_f64(), current.to_f64());
        n < c - 1e-10 * c.abs().max(1.0)
    } else {
        new < current
    }
}

/// One-shot alpha-expansion: see [`AlphaExpansion::solve`].
///
/// ```
/// use motif_retarget::alpha_expansion::{alpha_expansion, AlphaExpansionOptions, MrfEnergy};
/// // A chain of 4 sites, 3 labels, Potts smoothness of weight 2.
/// let edges = [[0, 1], [1, 2], [2, 3]];
/// let unary = [0, 5, 5, /**/ 5, 0, 5, /**/ 0, 5, 5, /**/ 0, 5, 5];
/// let energy = MrfEnergy::new(4, 3, &edges, |p, l| unary[p * 3 + l], |_, _, a, b| {
///     if a == b { 0i64 } else { 2 }
/// });
/// let r = alpha_expansion(&energy, &[0, 1, 0, 0], &AlphaExpansionOptions::default()).unwrap();
/// assert_eq!(r.labels, vec![0, 1, 0, 0]);
/// assert_eq!(r.energy, 4);
/// ```
pub fn alpha_expansion<C, D, V>(
    energy: &MrfEnergy<'_, C, D, V>,
    init: &[u32],
    options: &AlphaExpansionOptions,
) -> Result<AlphaExpansionResult<C>>
where
    C: Capacity,
    D: Fn(usize, usize) -> C + Sync,
    V: Fn(usize, usize, usize, usize) -> C + Sync,
{
    AlphaExpansion::new().solve(energy, init, options)
}
