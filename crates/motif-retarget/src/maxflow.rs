//! Boykov–Kolmogorov max-flow / min-cut with search-tree reuse.
//!
//! Implements the augmenting-path algorithm of Y. Boykov and V. Kolmogorov, "An experimental
//! comparison of min-cut/max-flow algorithms for energy minimization in vision", IEEE TPAMI 26(9),
//! 2004: two search trees S (rooted at the source) and T (rooted at the sink) grow from active
//! nodes until they touch (growth), the path through the touching arc is saturated
//! (augmentation), and nodes cut off from their tree look for a new parent in the same tree or
//! become free (adoption). Parents are chosen by the distance / timestamp heuristic of the
//! paper's section 3.3: a node remembers its distance to the terminal and the time that distance
//! was verified, so the origin check of a candidate parent stops early and prefers short paths.
//!
//! Tree reuse ([`Graph::maxflow_reuse`]): after a max-flow, terminal capacities can be changed
//! with [`Graph::add_tweights`] (the changed nodes are recorded, see [`Graph::mark_node`]) and the
//! next run continues from the previous flow *and* search trees instead of growing them again,
//! as in BK's `maxflow(reuse_trees = true)` and Kohli & Torr's dynamic graph cuts (ICCV 2005).
//!
//! Conventions:
//! - nodes are `usize` indices `0..num_nodes()`; a node in the [`Segment::Source`] segment after
//!   the max-flow is on the source side of the minimum cut;
//! - terminal capacities are stored as one signed residual per node (`source − sink`); the part
//!   common to both terminal links is flow straight through the node and is added to the flow
//!   value at once ([`Graph::add_tweights`]), so terminal capacities may also be *lowered* later;
//! - capacities are any [`Capacity`]: `i32`, `i64` (exact) or `f32`, `f64`. With floating-point
//!   capacities every augmentation saturates its bottleneck arc exactly (the bottleneck value is
//!   subtracted from itself), so the algorithm terminates; the reported flow carries the rounding
//!   of its additions (relative error about `augmentations × ε`), and the cut is exact for the
//!   residual graph the arithmetic produced. Capacities must not be NaN; a node's two terminal
//!   capacities must not both be infinite.
//!
//! Storage: an arena of nodes and a compressed adjacency array of arcs (arcs of a node are
//! contiguous; each arc knows its reverse "sister"), built by a counting sort when the max-flow
//! starts. The active queue and orphan queue are reused between runs; no allocation happens
//! inside the growth / augmentation / adoption loop.

use std::collections::VecDeque;
use std::fmt::Debug;
use std::ops::{Add, AddAssign, Mul, Neg, Sub, SubAssign};

/// Number types usable as arc capacities and energies.
///
/// Implemented for `i32`, `i64` (exact arithmetic; the caller keeps sums in range) and `f32`,
/// `f64` (see the module docs on rounding).
pub trait Capacity:
    Copy
    + PartialOrd
    + Default
    + Debug
    + Send
    + Sync
    + 'static
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Neg<Output = Self>
    + AddAssign
    + SubAssign
{
    /// Zero.
    const ZERO: Self;
    /// One.
    const ONE: Self;
    /// Whether the type is a floating-point type (comparisons of energies then use a tolerance).
    const IS_FLOAT: bool;
    /// The value as `f64` (for reports).
    fn to_f64(self) -> f64;
    /// Converts from `f64`, rounding to nearest and saturating for integer types.
    fn from_f64(x: f64) -> Self;
    /// True for NaN (never for integers).
    fn is_nan(self) -> bool;
    /// True for ±infinity (never for integers).
    fn is_infinite(self) -> bool;
}

macro_rules! impl_capacity_int {
    ($t:ty) => {
        impl Capacity for $t {
            const ZERO: Self = 0;
            const ONE: Self = 1;
            const IS_FLOAT: bool = false;
            #[inline]
            fn to_f64(self) -> f64 {
                self as f64
            }
            #[inline]
            fn from_f64(x: f64) -> Self {
                // `as` saturates and maps NaN to 0.
                x.round() as $t
            }
            #[inline]
            fn is_nan(self) -> bool {
                false
            }
            #[inline]
            fn is_infinite(self) -> bool {
                false
            }
        }
    };
}

macro_rules! impl_capacity_float {
    ($t:ty) => {
        impl Capacity for $t {
            const ZERO: Self = 0.0;
            const ONE: Self = 1.0;
            const IS_FLOAT: bool = true;
            #[inline]
            fn to_f64(self) -> f64 {
                self as f64
            }
            #[inline]
            fn from_f64(x: f64) -> Self {
                x as $t
            }
            #[inline]
            fn is_nan(self) -> bool {
                <$t>::is_nan(self)
            }
            #[inline]
            fn is_infinite(self) -> bool {
                <$t>::is_infinite(self)
            }
        }
    };
}

impl_capacity_int!(i32);
impl_capacity_int!(i64);
impl_capacity_float!(f32);
impl_capacity_float!(f64);

/// Which side of the minimum cut a node lies on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Segment {
    /// The source side (the node is reachable from the source in the residual graph, or free).
    Source,
    /// The sink side (the node reaches the sink in the residual graph).
    Sink,
}

/// Sentinel parent values; real parents are arc indices below these.
const NONE: u32 = u32::MAX;
const TERMINAL: u32 = u32::MAX - 1;
const ORPHAN: u32 = u32::MAX - 2;
/// Largest number of nodes or arcs (arc and node indices must stay below the sentinels).
const MAX_INDEX: usize = (u32::MAX - 3) as usize;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
enum Tree {
    Free,
    Source,
    Sink,
}

#[derive(Debug, Clone, Copy)]
struct Node<C> {
    /// Residual terminal capacity: > 0 towards the source link, < 0 towards the sink link.
    tr_cap: C,
    /// Arc from this node to its tree parent, or TERMINAL / ORPHAN / NONE.
    parent: u32,
    /// Time at which `dist` was last known to be exact.
    ts: u32,
    /// Distance (in arcs) to the tree's terminal, exact at time `ts`.
    dist: u32,
    tree: Tree,
    /// In the active queue (or the node being scanned).
    active: bool,
    /// In the list of nodes whose terminal capacity changed since the last run.
    marked: bool,
}

impl<C: Capacity> Default for Node<C> {
    fn default() -> Self {
        Node { tr_cap: C::ZERO, parent: NONE, ts: 0, dist: 0, tree: Tree::Free, active: false, marked: false }
    }
}

#[derive(Debug, Clone, Copy, Default)]
struct Arc<C> {
    head: u32,
    sister: u32,
    /// Residual capacity.
    rcap: C,
}

#[derive(Debug, Clone, Copy)]
struct PendingEdge<C> {
    a: u32,
    b: u32,
    cap: C,
    rev_cap: C,
}

/// A directed graph with two terminals (source, sink) and a Boykov–Kolmogorov max-flow solver.
///
/// Build it with [`Graph::new`], [`Graph::add_node`], [`Graph::add_tweights`] and
/// [`Graph::add_edge`], run [`Graph::maxflow`], then read the cut with [`Graph::what_segment`].
/// [`Graph::reset`] empties the graph but keeps every allocation, so one `Graph` can serve many
/// cuts (alpha-expansion builds one per move).
///
/// ```
/// use motif_retarget::maxflow::{Graph, Segment};
/// let mut g = Graph::<i64>::new(2, 1);
/// g.add_tweights(0, 5, 1); // source → 0 capacity 5, 0 → sink capacity 1
/// g.add_tweights(1, 2, 6);
/// g.add_edge(0, 1, 3, 4); // 0 → 1 capacity 3, 1 → 0 capacity 4
/// assert_eq!(g.maxflow(), 6);
/// assert_eq!(g.what_segment(0), Segment::Source);
/// assert_eq!(g.what_segment(1), Segment::Sink);
/// ```
#[derive(Debug, Clone)]
pub struct Graph<C: Capacity = f64> {
    nodes: Vec<Node<C>>,
    /// `arcs[arc_start[v]..arc_start[v + 1]]` leave node `v` (valid when `finalized`).
    arc_start: Vec<u32>,
    arcs: Vec<Arc<C>>,
    /// Edges added since the adjacency array was last built.
    pending: Vec<PendingEdge<C>>,
    /// Scratch for the counting sort.
    fill: Vec<u32>,
    /// Arc `a → b` of each edge, in the order the edges were added, when the adjacency array was
    /// last built from a reset graph (empty otherwise): see [`Graph::arc_of_edge`].
    edge_arc: Vec<u32>,
    /// The adjacency array holds every edge.
    finalized: bool,
    /// The search trees of the last run are consistent with the residual graph.
    trees_valid: bool,
    flow: C,
    time: u32,
    queue: VecDeque<u32>,
    orphans: VecDeque<u32>,
    changed: Vec<u32>,
    augmentations: u64,
}

impl<C: Capacity> Default for Graph<C> {
    fn default() -> Self {
        Graph::new(0, 0)
    }
}

#[inline]
fn min<C: Capacity>(a: C, b: C) -> C {
    if b < a { b } else { a }
}

impl<C: Capacity> Graph<C> {
    /// A graph with `num_nodes` nodes (no terminal capacity) and room for `edge_hint` edges.
    pub fn new(num_nodes: usize, edge_hint: usize) -> Self {
        let mut g = Graph {
            nodes: Vec::with_capacity(num_nodes),
            arc_start: Vec::with_capacity(num_nodes + 1),
            arcs: Vec::with_capacity(2 * edge_hint),
            pending: Vec::with_capacity(edge_hint),
            fill: Vec::with_capacity(num_nodes),
            edge_arc: Vec::new(),
            finalized: false,
            trees_valid: false,
            flow: C::ZERO,
            time: 0,
            queue: VecDeque::with_capacity(num_nodes),
            orphans: VecDeque::new(),
            changed: Vec::new(),
            augmentations: 0,
        };
        g.reset(num_nodes);
        g
    }

    /// Removes every edge and terminal capacity and sets the number of nodes to `num_nodes`,
    /// keeping the allocations for the next graph.
    ///
    /// # Panics
    /// If `num_nodes` exceeds `u32::MAX − 3`.
    pub fn reset(&mut self, num_nodes: usize) {
        assert!(num_nodes <= MAX_INDEX, "too many nodes for a max-flow graph: {num_nodes}");
        self.nodes.clear();
        self.nodes.resize(num_nodes, Node::default());
        self.arc_start.clear();
        self.arcs.clear();
        self.pending.clear();
        self.finalized = false;
        self.trees_valid = false;
        self.flow = C::ZERO;
        self.time = 0;
        self.queue.clear();
        self.orphans.clear();
        self.changed.clear();
        self.augmentations = 0;
    }

    /// Adds a node without terminal capacity and returns its index.
    ///
    /// # Panics
    /// If the graph already has `u32::MAX − 3` nodes.
    pub fn add_node(&mut self) -> usize {
        let i = self.nodes.len();
        assert!(i < MAX_INDEX, "too many nodes for a max-flow graph");
        self.nodes.push(Node::default());
        if self.finalized {
            let end = self.arc_start.last().copied().unwrap_or(0);
            if self.arc_start.is_empty() {
                self.arc_start.push(0);
            }
            self.arc_start.push(end);
        }
        i
    }

    /// About how many bytes a graph of `nodes` nodes and `edges` edges keeps after a max-flow
    /// and [`Graph::release_build_buffers`]: nodes, arcs, their index, the active and orphan
    /// queues and the list of changed nodes.
    pub fn bytes_for(nodes: usize, edges: usize) -> usize {
        nodes * (std::mem::size_of::<Node<C>>() + 24) + edges * (2 * std::mem::size_of::<Arc<C>>() + 4)
    }

    /// Frees the buffer that holds edges until the adjacency array is built (it is allocated
    /// again when edges are added): for graphs kept between max-flows whose edges are all added.
    pub fn release_build_buffers(&mut self) {
        self.finalize();
        self.pending = Vec::new();
    }

    /// Number of nodes (terminals not counted).
    pub fn num_nodes(&self) -> usize {
        self.nodes.len()
    }

    /// Number of edges added with [`Graph::add_edge`] (each is a pair of arcs).
    pub fn num_edges(&self) -> usize {
        self.arcs.len() / 2 + self.pending.len()
    }

    /// The current flow value: the capacity of the minimum cut after [`Graph::maxflow`].
    pub fn flow(&self) -> C {
        self.flow
    }

    /// Number of augmenting paths saturated since the graph was created or reset.
    pub fn augmentations(&self) -> u64 {
        self.augmentations
    }

    /// Adds `cap_source` to the capacity of the link source → `node` and `cap_sink` to the link
    /// `node` → sink. Calls accumulate. The part common to both links is flow that goes straight
    /// through the node: it is added to [`Graph::flow`] at once and only the difference is stored.
    /// Negative arguments are allowed as long as each link's total capacity stays non-negative
    /// (this lowers a capacity, e.g. between [`Graph::maxflow_reuse`] calls).
    ///
    /// After a max-flow the node is recorded as changed, so that [`Graph::maxflow_reuse`] repairs
    /// the search trees around it.
    ///
    /// # Panics
    /// If `node` is out of range.
    pub fn add_tweights(&mut self, node: usize, cap_source: C, cap_sink: C) {
        let n = &mut self.nodes[node];
        let (mut cs, mut ct) = (cap_source, cap_sink);
        let delta = n.tr_cap;
        if delta > C::ZERO {
            cs += delta;
        } else {
            ct -= delta;
        }
        self.flow += min(cs, ct);
        n.tr_cap = cs - ct;
        if self.trees_valid && !n.marked {
            n.marked = true;
            self.changed.push(node as u32);
        }
    }

    /// Adds the edge `a → b` with capacity `cap` and `b → a` with capacity `rev_cap`. Parallel
    /// edges are allowed. Adding an edge after a max-flow keeps the flow but discards the search
    /// trees (the next run grows them anew).
    ///
    /// # Panics
    /// If `a == b`, a node is out of range, a capacity is negative or NaN, or the graph already
    /// holds `(u32::MAX − 3) / 2` edges.
    pub fn add_edge(&mut self, a: usize, b: usize, cap: C, rev_cap: C) {
        assert!(a != b, "max-flow edge from node {a} to itself");
        assert!(a < self.nodes.len() && b < self.nodes.len(), "max-flow edge ({a}, {b}) out of range");
        assert!(cap >= C::ZERO && rev_cap >= C::ZERO, "max-flow edge capacities must be >= 0 (not NaN)");
        assert!(2 * (self.num_edges() + 1) <= MAX_INDEX, "too many edges for a max-flow graph");
        self.pending.push(PendingEdge { a: a as u32, b: b as u32, cap, rev_cap });
        self.finalized = false;
    }

    /// Records that the terminal capacities of `node` changed, so that the next
    /// [`Graph::maxflow_reuse`] re-examines it. [`Graph::add_tweights`] calls this itself after a
    /// max-flow; calling it again is harmless.
    ///
    /// # Panics
    /// If `node` is out of range.
    pub fn mark_node(&mut self, node: usize) {
        let n = &mut self.nodes[node];
        if !n.marked {
            n.marked = true;
            self.changed.push(node as u32);
        }
    }

    /// The arc `a → b` of the `e`-th edge added since the last [`Graph::reset`] (builds the
    /// adjacency array if edges are pending), for [`Graph::change_edge_capacity`]. The answer
    /// holds as long as no edge is added.
    ///
    /// # Panics
    /// If `e` is out of range, or edges were added after a max-flow (the arcs were re-collected
    /// and no longer follow the order the edges were added in).
    pub fn arc_of_edge(&mut self, e: usize) -> usize {
        self.finalize();
        assert!(
            self.edge_arc.len() * 2 == self.arcs.len(),
            "arc_of_edge: edges were added after a max-flow, so their order is lost"
        );
        self.edge_arc[e] as usize
    }

    /// Changes the capacities of an edge after a max-flow, keeping the flow: `d_cap` is added
    /// to the capacity of `arc` (from [`Graph::arc_of_edge`]) and `d_rev` to that of its reverse.
    /// A capacity may fall below the flow the arc carries: the excess `e` is then taken off the
    /// arc and routed through the terminals (source → tail and head → sink gain `e` each and
    /// the flow value falls by `e`), the reparametrisation of Kohli & Torr's dynamic graph cuts
    /// (ICCV 2005), which changes every cut's capacity by the same constant. Both ends are
    /// recorded as changed, so that [`Graph::maxflow_reuse`] repairs the search trees around
    /// them; the next run then gives the maximum flow of the changed graph.
    ///
    /// # Panics
    /// If `arc` is out of range, or a resulting capacity (the arc's plus its reverse's) is
    /// negative.
    pub fn change_edge_capacity(&mut self, arc: usize, d_cap: C, d_rev: C) {
        self.finalize();
        let sister = self.arcs[arc].sister as usize;
        let (tail, head) = (self.arcs[sister].head as usize, self.arcs[arc].head as usize);
        self.arcs[arc].rcap += d_cap;
        self.arcs[sister].rcap += d_rev;
        let (r, rs) = (self.arcs[arc].rcap, self.arcs[sister].rcap);
        assert!(r + rs >= C::ZERO, "change_edge_capacity: negative total capacity");
        if r < C::ZERO {
            // tail → head carries more than its capacity.
            self.arcs[arc].rcap = C::ZERO;
            self.arcs[sister].rcap = r + rs;
            self.add_tweights(tail, -r, C::ZERO);
            self.add_tweights(head, C::ZERO, -r);
            self.flow += r;
        } else if rs < C::ZERO {
            self.arcs[sister].rcap = C::ZERO;
            self.arcs[arc].rcap = r + rs;
            self.add_tweights(head, -rs, C::ZERO);
            self.add_tweights(tail, C::ZERO, -rs);
            self.flow += rs;
        }
        if self.trees_valid {
            self.mark_node(tail);
            self.mark_node(head);
        }
    }

    /// Computes the maximum flow from scratch (search trees grown anew; any flow already pushed
    /// by an earlier run is kept) and returns its value.
    pub fn maxflow(&mut self) -> C {
        self.run(false)
    }

    /// Like [`Graph::maxflow`], but continues from the search trees of the previous run, repairing
    /// them only around the nodes whose terminal capacities changed since (BK's
    /// `reuse_trees = true`). Falls back to a fresh run before the first max-flow or after edges
    /// were added. Both variants keep the flow already pushed; reusing the trees pays when the
    /// changes are few and local. On graphs whose old trees are deep (e.g. random capacities on a
    /// large grid) a fresh run, whose trees grow from every terminal at once, can be faster: see
    /// the `maxflow/*reuse*` benchmarks.
    pub fn maxflow_reuse(&mut self) -> C {
        self.run(true)
    }

    /// The side of the minimum cut `node` is on, after a max-flow. Free nodes (on neither search
    /// tree; either side gives a minimum cut) are reported as [`Segment::Source`].
    ///
    /// # Panics
    /// If `node` is out of range.
    pub fn what_segment(&self, node: usize) -> Segment {
        self.what_segment_or(node, Segment::Source)
    }

    /// Like [`Graph::what_segment`], with the side reported for free nodes chosen by the caller.
    ///
    /// # Panics
    /// If `node` is out of range.
    pub fn what_segment_or(&self, node: usize, free: Segment) -> Segment {
        match self.nodes[node].tree {
            Tree::Source => Segment::Source,
            Tree::Sink => Segment::Sink,
            Tree::Free => free,
        }
    }

    /// Builds the adjacency array from the pending edges (and the arcs already there, with their
    /// residual capacities). Returns true when the structure changed.
    fn finalize(&mut self) -> bool {
        if self.finalized {
            return false;
        }
        let n = self.nodes.len();
        self.edge_arc.clear();
        let in_order = self.arcs.is_empty();
        if !self.arcs.is_empty() {
            // Edges added after a run: re-collect the existing arcs with their residuals. The
            // trees name arcs by index, so the next run grows them anew (also when this is
            // called before it, by `arc_of_edge` or `change_edge_capacity`).
            self.trees_valid = false;
            for v in 0..self.arc_start.len().saturating_sub(1) {
                for a in self.arc_start[v] as usize..self.arc_start[v + 1] as usize {
                    let arc = self.arcs[a];
                    let s = arc.sister as usize;
                    if a < s {
                        self.pending.push(PendingEdge {
                            a: v as u32,
                            b: arc.head,
                            cap: arc.rcap,
                            rev_cap: self.arcs[s].rcap,
                        });
                    }
                }
            }
        }
        self.arc_start.clear();
        self.arc_start.resize(n + 1, 0);
        for e in &self.pending {
            self.arc_start[e.a as usize + 1] += 1;
            self.arc_start[e.b as usize + 1] += 1;
        }
        for v in 0..n {
            self.arc_start[v + 1] += self.arc_start[v];
        }
        self.fill.clear();
        self.fill.extend_from_slice(&self.arc_start[..n]);
        self.arcs.clear();
        self.arcs.resize(2 * self.pending.len(), Arc::default());
        for e in &self.pending {
            let i = self.fill[e.a as usize];
            self.fill[e.a as usize] += 1;
            let j = self.fill[e.b as usize];
            self.fill[e.b as usize] += 1;
            self.arcs[i as usize] = Arc { head: e.b, sister: j, rcap: e.cap };
            self.arcs[j as usize] = Arc { head: e.a, sister: i, rcap: e.rev_cap };
            if in_order {
                self.edge_arc.push(i);
            }
        }
        self.pending.clear();
        self.finalized = true;
        true
    }

    #[inline]
    fn make_active(&mut self, v: u32) {
        let n = &mut self.nodes[v as usize];
        if !n.active {
            n.active = true;
            self.queue.push_back(v);
        }
    }

    #[inline]
    fn set_orphan(&mut self, v: u32) {
        self.nodes[v as usize].parent = ORPHAN;
        self.orphans.push_back(v);
    }

    /// Saturates every path source → p → q → sink of length one arc in one pass over the arcs:
    /// these are most augmenting paths of an expansion-move graph, and pushing them before the
    /// trees exist avoids one growth, augmentation and orphan adoption each.
    fn push_direct_paths(&mut self) {
        for p in 0..self.nodes.len() {
            if self.nodes[p].tr_cap <= C::ZERO {
                continue;
            }
            let (start, end) = self.arc_range(p);
            for a in start..end {
                let arc = self.arcs[a];
                let q = arc.head as usize;
                let tq = self.nodes[q].tr_cap;
                if arc.rcap > C::ZERO && tq < C::ZERO {
                    let b = min(min(self.nodes[p].tr_cap, arc.rcap), -tq);
                    self.arcs[a].rcap -= b;
                    self.arcs[arc.sister as usize].rcap += b;
                    self.nodes[p].tr_cap -= b;
                    self.nodes[q].tr_cap += b;
                    self.flow += b;
                    if self.nodes[p].tr_cap <= C::ZERO {
                        break;
                    }
                }
            }
        }
    }

    /// Every node with terminal residual becomes a root of its tree; all others are free.
    fn init_fresh(&mut self) {
        self.push_direct_paths();
        self.queue.clear();
        self.orphans.clear();
        self.time = 0;
        for n in &mut self.nodes {
            n.marked = false;
            n.active = false;
        }
        self.changed.clear();
        for v in 0..self.nodes.len() {
            let n = &mut self.nodes[v];
            n.ts = 0;
            n.dist = 1;
            if n.tr_cap > C::ZERO {
                n.tree = Tree::Source;
                n.parent = TERMINAL;
            } else if n.tr_cap < C::ZERO {
                n.tree = Tree::Sink;
                n.parent = TERMINAL;
            } else {
                n.tree = Tree::Free;
                n.parent = NONE;
                continue;
            }
            self.make_active(v as u32);
        }
    }

    /// Repairs the previous search trees around the nodes whose terminal capacity changed.
    fn init_reuse(&mut self) {
        self.queue.clear();
        self.orphans.clear();
        self.advance_time();
        let changed = std::mem::take(&mut self.changed);
        for &v in &changed {
            let vi = v as usize;
            self.nodes[vi].marked = false;
            let tc = self.nodes[vi].tr_cap;
            let new_tree = if tc > C::ZERO {
                Tree::Source
            } else if tc < C::ZERO {
                Tree::Sink
            } else {
                Tree::Free
            };
            let old_tree = self.nodes[vi].tree;
            if new_tree == Tree::Free {
                // No terminal residual left: a root loses its parent; other nodes keep theirs
                // while the arc to it keeps residual capacity (an edge's capacity may have
                // changed). A node still in a tree scans its arcs again: a changed edge may
                // offer a new path.
                let parent = self.nodes[vi].parent;
                if parent == TERMINAL {
                    self.set_orphan(v);
                } else if parent < ORPHAN && old_tree != Tree::Free {
                    let a = parent as usize;
                    let cap = if old_tree == Tree::Source {
                        self.arcs[self.arcs[a].sister as usize].rcap
                    } else {
                        self.arcs[a].rcap
                    };
                    if cap <= C::ZERO {
                        self.set_orphan(v);
                    }
                }
                if old_tree != Tree::Free {
                    self.make_active(v);
                }
                continue;
            }
            if old_tree != Tree::Free && old_tree != new_tree {
                // v jumps to the other tree without passing through "free": its children in the
                // old tree lose their parent, and old-tree neighbours with residual capacity
                // towards v now hold augmenting paths, so they must be scanned again (v alone
                // may lose its terminal link before it has drained them all).
                let (s, e) = self.arc_range(vi);
                for a in s..e {
                    let arc = self.arcs[a];
                    let q = arc.head;
                    let nq = self.nodes[q as usize];
                    if nq.tree != old_tree {
                        continue;
                    }
                    let cap =
                        if old_tree == Tree::Source { self.arcs[arc.sister as usize].rcap } else { arc.rcap };
                    if cap > C::ZERO {
                        self.make_active(q);
                    }
                    if nq.parent < ORPHAN && self.arcs[nq.parent as usize].head == v {
                        self.set_orphan(q);
                    }
                }
            }
            let time = self.time;
            let n = &mut self.nodes[vi];
            n.tree = new_tree;
            n.parent = TERMINAL;
            n.ts = time;
            n.dist = 1;
            self.make_active(v);
        }
        self.changed = changed;
        self.changed.clear();
        self.adopt();
    }

    #[inline]
    fn arc_range(&self, v: usize) -> (usize, usize) {
        (self.arc_start[v] as usize, self.arc_start[v + 1] as usize)
    }

    fn advance_time(&mut self) {
        if self.time == u32::MAX {
            // Timestamps only compare within a run; restart them rather than wrap.
            for n in &mut self.nodes {
                n.ts = 0;
            }
            self.time = 0;
        }
        self.time += 1;
    }

    fn run(&mut self, reuse: bool) -> C {
        let structure_changed = self.finalize();
        if reuse && self.trees_valid && !structure_changed {
            self.init_reuse();
        } else {
            self.init_fresh();
        }
        self.trees_valid = true;

        let mut current = NONE;
        loop {
            let p = if current != NONE && self.nodes[current as usize].tree != Tree::Free {
                current
            } else {
                if current != NONE {
                    self.nodes[current as usize].active = false;
                }
                match self.next_active() {
                    Some(p) => p,
                    None => break,
                }
            };
            match self.grow(p as usize) {
                Some((mid, s_node, t_node)) => {
                    current = p;
                    self.augment(mid, s_node, t_node);
                    self.advance_time();
                    self.adopt();
                }
                None => {
                    self.nodes[p as usize].active = false;
                    current = NONE;
                }
            }
        }
        self.flow
    }

    fn next_active(&mut self) -> Option<u32> {
        while let Some(p) = self.queue.pop_front() {
            if self.nodes[p as usize].tree != Tree::Free {
                return Some(p);
            }
            self.nodes[p as usize].active = false;
        }
        None
    }

    /// Scans the arcs of active node `p`: free neighbours join its tree; a neighbour in the other
    /// tree closes an augmenting path, returned as (arc from the S side to the T side, S node,
    /// T node).
    fn grow(&mut self, p: usize) -> Option<(usize, usize, usize)> {
        let (start, end) = self.arc_range(p);
        let np = self.nodes[p];
        let (ts_p, dist_p) = (np.ts, np.dist);
        let nodes = &mut self.nodes;
        let arcs = &self.arcs;
        let queue = &mut self.queue;
        if np.tree == Tree::Source {
            for a in start..end {
                let arc = arcs[a];
                if arc.rcap > C::ZERO {
                    let q = arc.head as usize;
                    let nq = &mut nodes[q];
                    match nq.tree {
                        Tree::Free => {
                            nq.tree = Tree::Source;
                            nq.parent = arc.sister;
                            nq.ts = ts_p;
                            nq.dist = dist_p + 1;
                            if !nq.active {
                                nq.active = true;
                                queue.push_back(q as u32);
                            }
                        }
                        Tree::Source => {
                            // Distance heuristic: adopt q if p offers a shorter, not older path.
                            // Timestamps never decrease towards the root and distances strictly
                            // decrease along equal timestamps, so p cannot be q's descendant here.
                            if nq.ts <= ts_p && nq.dist > dist_p {
                                nq.parent = arc.sister;
                                nq.ts = ts_p;
                                nq.dist = dist_p + 1;
                            }
                        }
                        Tree::Sink => return Some((a, p, q)),
                    }
                }
            }
        } else {
            for a in start..end {
                let arc = arcs[a];
                let s = arc.sister as usize;
                if arcs[s].rcap > C::ZERO {
                    let q = arc.head as usize;
                    let nq = &mut nodes[q];
                    match nq.tree {
                        Tree::Free => {
                            nq.tree = Tree::Sink;
                            nq.parent = arc.sister;
                            nq.ts = ts_p;
                            nq.dist = dist_p + 1;
                            if !nq.active {
                                nq.active = true;
                                queue.push_back(q as u32);
                            }
                        }
                        Tree::Sink => {
                            if nq.ts <= ts_p && nq.dist > dist_p {
                                nq.parent = arc.sister;
                                nq.ts = ts_p;
                                nq.dist = dist_p + 1;
                            }
                        }
                        Tree::Source => return Some((s, q, p)),
                    }
                }
            }
        }
        None
    }

    /// Pushes the bottleneck capacity along source → … → s_node → t_node → … → sink; arcs that
    /// saturate orphan their child.
    fn augment(&mut self, mid: usize, s_node: usize, t_node: usize) {
        self.augmentations += 1;
        // Bottleneck.
        let mut b = self.arcs[mid].rcap;
        let mut i = s_node;
        loop {
            let a = self.nodes[i].parent;
            if a == TERMINAL {
                break;
            }
            let arc = self.arcs[a as usize];
            b = min(b, self.arcs[arc.sister as usize].rcap);
            i = arc.head as usize;
        }
        b = min(b, self.nodes[i].tr_cap);
        let mut i = t_node;
        loop {
            let a = self.nodes[i].parent;
            if a == TERMINAL {
                break;
            }
            let arc = self.arcs[a as usize];
            b = min(b, arc.rcap);
            i = arc.head as usize;
        }
        b = min(b, -self.nodes[i].tr_cap);

        // Push.
        let sister = self.arcs[mid].sister as usize;
        self.arcs[sister].rcap += b;
        self.arcs[mid].rcap -= b;
        let mut i = s_node;
        loop {
            let a = self.nodes[i].parent;
            if a == TERMINAL {
                break;
            }
            let arc = self.arcs[a as usize];
            let s = arc.sister as usize;
            self.arcs[a as usize].rcap += b;
            self.arcs[s].rcap -= b;
            if self.arcs[s].rcap <= C::ZERO {
                self.set_orphan(i as u32);
            }
            i = arc.head as usize;
        }
        self.nodes[i].tr_cap -= b;
        if self.nodes[i].tr_cap <= C::ZERO {
            self.set_orphan(i as u32);
        }
        let mut i = t_node;
        loop {
            let a = self.nodes[i].parent;
            if a == TERMINAL {
                break;
            }
            let arc = self.arcs[a as usize];
            self.arcs[arc.sister as usize].rcap += b;
            self.arcs[a as usize].rcap -= b;
            if self.arcs[a as usize].rcap <= C::ZERO {
                self.set_orphan(i as u32);
            }
            i = arc.head as usize;
        }
        self.nodes[i].tr_cap += b;
        if self.nodes[i].tr_cap >= C::ZERO {
            self.set_orphan(i as u32);
        }
        self.flow += b;
    }

    /// Distance from `q` to its tree's terminal if the path of parents reaches the terminal
    /// (not an orphan); stamps the nodes walked with the current time and their exact distance.
    fn origin_distance(&mut self, q: usize) -> Option<u32> {
        let time = self.time;
        let mut d: u32 = 0;
        let mut j = q;
        loop {
            let nj = self.nodes[j];
            if nj.ts == time {
                d += nj.dist;
                break;
            }
            d += 1;
            match nj.parent {
                TERMINAL => {
                    let n = &mut self.nodes[j];
                    n.ts = time;
                    n.dist = 1;
                    break;
                }
                ORPHAN | NONE => return None,
                a => j = self.arcs[a as usize].head as usize,
            }
        }
        let mut j = q;
        let mut dd = d;
        while self.nodes[j].ts != time {
            let n = &mut self.nodes[j];
            n.ts = time;
            n.dist = dd;
            dd -= 1;
            j = self.arcs[n.parent as usize].head as usize;
        }
        Some(d)
    }

    fn adopt(&mut self) {
        while let Some(p) = self.orphans.pop_front() {
            if self.nodes[p as usize].parent == ORPHAN {
                self.process_orphan(p as usize);
            }
        }
    }

    /// Finds `p` a new parent in its tree (the closest valid one), or frees it.
    fn process_orphan(&mut self, p: usize) {
        let tree = self.nodes[p].tree;
        let (start, end) = self.arc_range(p);
        let mut best_arc = NONE;
        let mut best_d = u32::MAX;
        for a in start..end {
            let arc = self.arcs[a];
            let cap = if tree == Tree::Source { self.arcs[arc.sister as usize].rcap } else { arc.rcap };
            if cap > C::ZERO && self.nodes[arc.head as usize].tree == tree {
                match self.origin_distance(arc.head as usize) {
                    Some(d) if d < best_d => {
                        best_d = d;
                        best_arc = a as u32;
                    }
                    _ => {}
                }
            }
        }
        if best_arc != NONE {
            let time = self.time;
            let n = &mut self.nodes[p];
            n.parent = best_arc;
            n.ts = time;
            n.dist = best_d + 1;
            return;
        }
        // No parent: p becomes free; its children become orphans and the neighbours that could
        // adopt it later become active.
        for a in start..end {
            let arc = self.arcs[a];
            let q = arc.head;
            let nq = self.nodes[q as usize];
            if nq.tree != tree {
                continue;
            }
            let cap = if tree == Tree::Source { self.arcs[arc.sister as usize].rcap } else { arc.rcap };
            if cap > C::ZERO {
                self.make_active(q);
            }
            if nq.parent < ORPHAN && self.arcs[nq.parent as usize].head as usize == p {
                self.set_orphan(q);
            }
        }
        let n = &mut self.nodes[p];
        n.tree = Tree::Free;
        n.parent = NONE;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    impl<C: Capacity> Graph<C> {
        /// Checks the search-tree invariants after a run: tree arcs have residual capacity,
        /// roots have terminal residual, S and T are closed (so both cuts are minimal).
        fn check_trees(&self) -> std::result::Result<(), String> {
            for v in 0..self.nodes.len() {
                let n = self.nodes[v];
                match n.tree {
                    Tree::Free => {
                        if n.tr_cap != C::ZERO {
                            return Err(format!("free node {v} has terminal residual {:?}", n.tr_cap));
                        }
                    }
                    t => {
                        if n.parent == TERMINAL {
                            let ok = if t == Tree::Source { n.tr_cap > C::ZERO } else { n.tr_cap < C::ZERO };
                            if !ok {
                                return Err(format!("root {v} ({t:?}) has tr_cap {:?}", n.tr_cap));
                            }
                        } else if n.parent >= ORPHAN {
                            return Err(format!("node {v} in {t:?} has parent {}", n.parent));
                        } else {
                            let a = self.arcs[n.parent as usize];
                            if self.nodes[a.head as usize].tree != t {
                                return Err(format!("node {v}: parent in another tree"));
                            }
                            let cap =
                                if t == Tree::Source { self.arcs[a.sister as usize].rcap } else { a.rcap };
                            if cap <= C::ZERO {
                                return Err(format!("node {v}: saturated parent arc"));
                            }
                        }
                        if t == Tree::Source && n.tr_cap < C::ZERO || t == Tree::Sink && n.tr_cap > C::ZERO {
                            return Err(format!("node {v} in {t:?} with tr_cap {:?}", n.tr_cap));
                        }
                    }
                }
                for a in self.arc_start[v] as usize..self.arc_start[v + 1] as usize {
                    let arc = self.arcs[a];
                    let w = arc.head as usize;
                    if arc.rcap > C::ZERO {
                        let (tv, tw) = (n.tree, self.nodes[w].tree);
                        if tv == Tree::Source && tw != Tree::Source {
                            return Err(format!("residual arc {v}->{w} leaves S (to {tw:?})"));
                        }
                        if tw == Tree::Sink && tv != Tree::Sink {
                            return Err(format!("residual arc {v}->{w} enters T (from {tv:?})"));
                        }
                    }
                }
            }
            Ok(())
        }
    }

    #[test]
    fn reuse_keeps_tree_invariants() {
        for seed in 0..300u64 {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let (mut tw, edges) = random_network(&mut rng);
            let n = tw.len();
            let mut g = fresh(&tw, &edges);
            g.check_trees().unwrap_or_else(|e| panic!("seed {seed} fresh: {e}"));
            for round in 0..8 {
                for _ in 0..rng.random_range(1..=4) {
                    let v = rng.random_range(0..n);
                    let new = (rng.random_range(0..=20), rng.random_range(0..=20));
                    g.add_tweights(v, new.0 - tw[v].0, new.1 - tw[v].1);
                    tw[v] = new;
                }
                g.maxflow_reuse();
                g.check_trees().unwrap_or_else(|e| panic!("seed {seed} round {round}: {e}"));
            }
        }
    }

    /// A random network of 2–30 nodes: terminal capacities (source, sink) per node and edges
    /// (a, b, capacity a → b, capacity b → a), each pair joined with probability 0.2.
    fn random_network(rng: &mut rand_chacha::ChaCha8Rng) -> (Vec<(i64, i64)>, Vec<(usize, usize, i64, i64)>) {
        let n = rng.random_range(2..=30);
        let tw = (0..n).map(|_| (rng.random_range(0..=20), rng.random_range(0..=20))).collect();
        let mut edges = Vec::new();
        for a in 0..n {
            for b in a + 1..n {
                if rng.random_bool(0.2) {
                    edges.push((a, b, rng.random_range(0..=20), rng.random_range(0..=20)));
                }
            }
        }
        (tw, edges)
    }

    /// A fresh graph of the same capacities: its flow and its cut (both the smallest and the
    /// largest source side) are the oracle for a graph changed after a max-flow.
    fn fresh(tw: &[(i64, i64)], edges: &[(usize, usize, i64, i64)]) -> Graph<i64> {
        let mut g = Graph::<i64>::new(tw.len(), edges.len());
        for (v, &(s, t)) in tw.iter().enumerate() {
            g.add_tweights(v, s, t);
        }
        for &(a, b, c, r) in edges {
            g.add_edge(a, b, c, r);
        }
        g.maxflow();
        g
    }

    #[test]
    fn reuse_after_edge_capacity_changes_matches_a_fresh_max_flow() {
        for seed in 0..300u64 {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let (mut tw, mut edges) = random_network(&mut rng);
            let n = tw.len();
            let mut g = fresh(&tw, &edges);
            let arcs: Vec<usize> = (0..edges.len()).map(|e| g.arc_of_edge(e)).collect();
            for round in 0..8 {
                for _ in 0..rng.random_range(0..=3) {
                    let v = rng.random_range(0..n);
                    let new = (rng.random_range(0..=20), rng.random_range(0..=20));
                    g.add_tweights(v, new.0 - tw[v].0, new.1 - tw[v].1);
                    tw[v] = new;
                }
                for _ in 0..rng.random_range(0..=4) {
                    if edges.is_empty() {
                        break;
                    }
                    let k = rng.random_range(0..edges.len());
                    // Often to zero, as an expansion move does when an end becomes fixed.
                    let (c, r) = if rng.random_bool(0.3) {
                        (0, 0)
                    } else {
                        (rng.random_range(0..=20), rng.random_range(0..=20))
                    };
                    g.change_edge_capacity(arcs[k], c - edges[k].2, r - edges[k].3);
                    (edges[k].2, edges[k].3) = (c, r);
                }
                let flow = g.maxflow_reuse();
                g.check_trees().unwrap_or_else(|e| panic!("seed {seed} round {round}: {e}"));
                let f = fresh(&tw, &edges);
                assert_eq!(flow, f.flow(), "seed {seed} round {round}: flow");
                for v in 0..n {
                    for free in [Segment::Source, Segment::Sink] {
                        assert_eq!(
                            g.what_segment_or(v, free),
                            f.what_segment_or(v, free),
                            "seed {seed} round {round}: node {v}, free nodes on the {free:?} side"
                        );
                    }
                }
            }
        }
    }

    /// Edges added after a max-flow renumber the arcs; building the adjacency array before the
    /// next run (as `release_build_buffers` does) must not leave trees naming the old arcs.
    #[test]
    fn edges_added_after_a_run_and_built_early_grow_the_trees_anew() {
        for seed in 0..300u64 {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let n = rng.random_range(2..=20);
            let tw: Vec<(i64, i64)> =
                (0..n).map(|_| (rng.random_range(0..=20), rng.random_range(0..=20))).collect();
            let mut edges = Vec::new();
            let add = |rng: &mut rand_chacha::ChaCha8Rng, edges: &mut Vec<(usize, usize, i64, i64)>| {
                let a = rng.random_range(0..n);
                let b = (a + rng.random_range(1..n)) % n;
                edges.push((a, b, rng.random_range(0..=20), rng.random_range(0..=20)));
            };
            for _ in 0..2 * n {
                add(&mut rng, &mut edges);
            }
            let mut g = fresh(&tw, &edges);
            let before = edges.len();
            for _ in 0..rng.random_range(1..=n) {
                add(&mut rng, &mut edges);
            }
            for &(a, b, c, r) in &edges[before..] {
                g.add_edge(a, b, c, r);
            }
            g.release_build_buffers();
            assert_eq!(g.maxflow_reuse(), fresh(&tw, &edges).flow(), "seed {seed}");
            g.check_trees().unwrap_or_else(|e| panic!("seed {seed}: {e}"));
        }
    }

    #[test]
    fn two_nodes() {
        let mut g = Graph::<i64>::new(2, 1);
        g.add_tweights(0, 5, 1);
        g.add_tweights(1, 2, 6);
        g.add_edge(0, 1, 3, 4);
        assert_eq!(g.maxflow(), 6);
        assert_eq!(g.what_segment(0), Segment::Source);
        assert_eq!(g.what_segment(1), Segment::Sink);
    }

    #[test]
    fn tweights_cancel_into_flow() {
        let mut g = Graph::<i64>::new(1, 0);
        g.add_tweights(0, 3, 5);
        assert_eq!(g.flow(), 3);
        g.add_tweights(0, 4, 0);
        assert_eq!(g.flow(), 5);
        assert_eq!(g.maxflow(), 5);
        assert_eq!(g.what_segment(0), Segment::Source);
    }

    #[test]
    fn reuse_after_lowering_capacity() {
        let mut g = Graph::<i64>::new(3, 2);
        g.add_tweights(0, 10, 0);
        g.add_tweights(2, 0, 10);
        g.add_edge(0, 1, 4, 0);
        g.add_edge(1, 2, 7, 0);
        assert_eq!(g.maxflow(), 4);
        g.add_tweights(1, 5, 0);
        assert_eq!(g.maxflow_reuse(), 7);
        g.add_tweights(1, -5, 0);
        assert_eq!(g.maxflow_reuse(), 4);
        g.add_tweights(0, -8, 0);
        assert_eq!(g.maxflow_reuse(), 2);
    }

    #[test]
    fn floats() {
        let mut g = Graph::<f64>::new(2, 1);
        g.add_tweights(0, 0.5, 0.0);
        g.add_tweights(1, 0.0, 0.25);
        g.add_edge(0, 1, 1.0, 0.0);
        assert_eq!(g.maxflow(), 0.25);
    }
}
