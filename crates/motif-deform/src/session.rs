//! The deformation session: precompute once (sampling, basis, lifting, Laplacian), factorise once
//! per handle set, solve per frame (thesis 3.4–3.5, Table 3.1's "pre-factoring" / "5 iterations"
//! / "lifting").

use std::time::Instant;

use serde::{Deserialize, Serialize};

use motif_core::TriMesh;
use motif_core::geometry::{Mat4, Point3};
use motif_core::procedural::SymmetryAnnotation;
use motif_core::progress::{NoProgress, Progress};

use crate::annotation::{ResolvedAnnotation, check_mesh, resolve_annotation};
use crate::basis::SymmetricBasis;
use crate::editing::{EditingOptions, HandleSystem, Workspace, select_handle_samples, solve_frame};
use crate::error::{DeformError, Result};
use crate::handles::Handle;
use crate::laplace::{RotationPlan, SamplingGraph};
use crate::lift::{LiftOptions, Lifting};
use crate::residual::{SurfaceDistance, element_residual};
use crate::symmetric_sampling::{
    SymmetricSampling, SymmetricSamplingOptions, add_orbits, symmetric_sampling,
};

/// Rounds of seeding orbits at vertices without a symmetry-consistent support.
const MAX_SUPPORT_ROUNDS: usize = 4;

/// Whether the annotation's symmetries are preserved.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SymmetryMode {
    /// Deform in the space of symmetry-preserving displacements (default).
    Preserve,
    /// The same pipeline with only the identity (the `--no-symmetry` comparison).
    Ignore,
}

/// What to do when an annotation transform does not map its region onto the shape within the
/// annotation's tolerance.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AnnotationValidation {
    /// Fail with [`DeformError::SymmetryMismatch`] (default).
    Strict,
    /// Warn (see [`DeformSession::warnings`]) and sample on the approximate symmetry: the
    /// deformation is then exactly symmetric on the samples only.
    Force,
}

/// Largest deviation from orthogonality (entries of |OᵀO − I|) a handle transform may have.
/// Handles move rigidly (`motif_handles_v1`); this is loose enough for rotations composed in
/// single precision by a page, and catches any real scale, shear or flattening.
pub const HANDLE_RIGIDITY_TOLERANCE: f64 = 1e-3;

/// Options of a deformation session.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct DeformOptions {
    /// Preserve the symmetries or ignore them; default preserve.
    pub symmetry: SymmetryMode,
    /// Strict or forced annotation validation; default strict.
    pub validation: AnnotationValidation,
    /// Symmetric Poisson-disc sampling (thesis 3.4).
    pub sampling: SymmetricSamplingOptions,
    /// Lifting to the mesh (thesis 3.4).
    pub lift: LiftOptions,
    /// Co-rotated Laplace editing (thesis 3.5).
    pub editing: EditingOptions,
}

impl Default for DeformOptions {
    fn default() -> Self {
        DeformOptions {
            symmetry: SymmetryMode::Preserve,
            validation: AnnotationValidation::Strict,
            sampling: SymmetricSamplingOptions::default(),
            lift: LiftOptions::default(),
            editing: EditingOptions::default(),
        }
    }
}

/// Wall-clock timings, milliseconds.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Timings {
    /// Resolving and validating the annotation.
    pub annotation_ms: f64,
    /// Symmetric sampling (including the radius search of a target count).
    pub sampling_ms: f64,
    /// Basis, sampling graph and Laplace coordinates.
    pub basis_ms: f64,
    /// Building the lifting matrix `W` (including orbits seeded at vertices without support).
    pub lift_setup_ms: f64,
    /// Selecting handle samples, assembling and factorising eq. 3.4 (last `set_handles`).
    pub prefactor_ms: f64,
    /// The iterations of the last `solve` (sampling only).
    pub solve_ms: f64,
    /// Lifting of the last `solve` to the mesh.
    pub lift_ms: f64,
}

/// Sizes and timings of a session.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct DeformStats {
    /// Mesh vertices.
    pub vertices: usize,
    /// Bounding-box diagonal of the rest mesh.
    pub diagonal: f64,
    /// Samples.
    pub samples: usize,
    /// Orbits (seeds).
    pub orbits: usize,
    /// Orbits on transformation-invariant sets (reduced basis).
    pub degenerate_orbits: usize,
    /// Dimension of the space of symmetry-preserving displacements (columns of `U`).
    pub dof: usize,
    /// Sampling radius `r`, mesh units.
    pub radius: f64,
    /// Edges of the sampling graph.
    pub graph_edges: usize,
    /// Rotations fitted by SVD per co-rotation iteration (the others follow their orbit's seed).
    pub rotation_fits: usize,
    /// Non-zeros of the lifting matrix `W` as stored (representative rows only with
    /// [`crate::LiftEvaluation::PerOrbit`]).
    pub lift_nonzeros: usize,
    /// Rows of `W` stored (vertex-orbit representatives, or all vertices).
    pub lift_rows: usize,
    /// Vertices with an empty symmetry-consistent support, lifted from their nearest samples
    /// (exactness not guaranteed there).
    pub fallback_vertices: usize,
    /// Symmetries used (0 when ignoring symmetry).
    pub symmetries: usize,
    /// Handles of the current handle set.
    pub handles: usize,
    /// Samples selected by the handles.
    pub handle_samples: usize,
    /// Absolute α of the current handle set.
    pub alpha: f64,
    /// True when eq. 3.4 is factorised sparsely (dof ≥ [`crate::editing::DENSE_DOF_LIMIT`]).
    pub sparse_factor: bool,
    /// Co-rotation iterations per solve.
    pub iterations: usize,
    /// Timings.
    pub timings: Timings,
}

/// How closely a handle's samples reached their targets in the last solve.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct HandleFit {
    /// Handle index.
    pub handle: usize,
    /// Samples of the handle.
    pub samples: usize,
    /// Largest distance of a handle sample from its target, relative to the diagonal.
    pub max_error: f64,
    /// Root-mean-square distance, relative to the diagonal.
    pub rms_error: f64,
}

/// A symmetry-preserving deformation session on one mesh and annotation.
///
/// ```
/// use motif_core::procedural::{fan, FanOptions, Region, rotation_about};
/// use motif_deform::{DeformOptions, DeformSession, Handle};
///
/// let ex = fan(&FanOptions::default()).unwrap();
/// let mut s = DeformSession::new(&ex.mesh, &ex.structure.symmetry, &DeformOptions::default()).unwrap();
/// s.set_handles(&[
///     Handle::fixed(Region::Sphere { center: [0.0; 3], radius: 0.06 }),
///     Handle::fixed(Region::Sphere { center: [0.3, 0.0, 0.0], radius: 0.04 }),
/// ]).unwrap();
/// let lift = motif_core::procedural::translation([0.0, 0.0, 0.05]);
/// let deformed = s.solve(&[motif_core::geometry::IDENTITY4, lift]).unwrap();
/// assert_eq!(deformed.len(), ex.mesh.num_vertices());
/// ```
#[derive(Debug, Clone)]
pub struct DeformSession {
    rest: Vec<Point3>,
    mesh: TriMesh,
    resolved: ResolvedAnnotation,
    sampling: SymmetricSampling,
    basis: SymmetricBasis,
    graph: SamplingGraph,
    plan: RotationPlan,
    delta: Vec<Point3>,
    lifting: Lifting,
    options: DeformOptions,
    system: Option<HandleSystem>,
    workspace: Workspace,
    positions: Vec<Point3>,
    lift_work: Vec<Point3>,
    fits: Vec<HandleFit>,
    /// The vertices each handle's region holds (set with the handles).
    handle_vertices: Vec<Vec<u32>>,
    warnings: Vec<String>,
    stats: DeformStats,
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

impl DeformSession {
    /// Precomputes everything that does not depend on the handles: resolves and validates the
    /// annotation (ignored with [`SymmetryMode::Ignore`]), samples symmetrically, builds the basis
    /// `U`, the sampling graph and Laplace coordinates, and the lifting matrix `W`.
    pub fn new(
        mesh: &TriMesh,
        annotation: &SymmetryAnnotation,
        options: &DeformOptions,
    ) -> Result<DeformSession> {
        Self::with_progress(mesh, annotation, options, &NoProgress)
    }

    /// [`DeformSession::new`], reporting its stages (`annotation`, `sampling`, `lifting`,
    /// `basis`) to `progress`. A front end stops the precomputation by unwinding out of a
    /// progress call (the studio's cancel): stages are the points where that can happen.
    pub fn with_progress(
        mesh: &TriMesh,
        annotation: &SymmetryAnnotation,
        options: &DeformOptions,
        progress: &dyn Progress,
    ) -> Result<DeformSession> {
        progress.start("annotation", 0);
        let diag = check_mesh(mesh)?;
        options.editing.validate()?;
        let mut warnings = Vec::new();
        let mut timings = Timings::default();
        let t = Instant::now();
        let resolved = match options.symmetry {
            SymmetryMode::Preserve => {
                let r = resolve_annotation(mesh, annotation)?;
                warnings.extend(r.warnings.iter().cloned());
                validate_fit(mesh, &r, options.validation, &mut warnings)?;
                r
            }
            SymmetryMode::Ignore => {
                ResolvedAnnotation::identity_only(diag, annotation.tolerance.clamp(1e-12, 0.5))
            }
        };
        timings.annotation_ms = ms(t);
        progress.start("sampling", 0);
        let t = Instant::now();
        let sampling = symmetric_sampling(mesh, &resolved, &options.sampling)?;
        timings.sampling_ms = ms(t);
        // A count the capped radius search could not come near (symmetric_sampling's
        // MAX_RADIUS_OVER_GUESS): the orbits are large, which the user should hear of, as the
        // solve's time and memory grow with them.
        if let crate::symmetric_sampling::SampleSpacing::Count(n) = options.sampling.spacing
            && sampling.len() > 2 * n
        {
            let largest = sampling.orbits.iter().map(|o| o.len).max().unwrap_or(0);
            warnings.push(format!(
                "symmetric sampling: {} samples instead of about {n}, as an orbit of the annotation's \
                 symmetries holds {largest} images (symmetries that hold only approximately, forced, \
                 generate far more transforms than their groups have): the solve is slower; a \
                 corrected annotation avoids it",
                sampling.len()
            ));
        }
        progress.start("lifting", MAX_SUPPORT_ROUNDS as u64 + 1);
        let t = Instant::now();
        let mut sampling = sampling;
        let mut lifting = Lifting::new(mesh, &resolved, &sampling, &options.lift)?;
        progress.inc(1);
        // Vertices whose symmetry-consistent support is empty (e.g. on an edge where four cells of
        // a lattice meet): seed orbits right there, so every cell gets a sample at that vertex.
        for _ in 0..MAX_SUPPORT_ROUNDS {
            if resolved.symmetries.is_empty() || lifting.fallback_vertices() == 0 {
                break;
            }
            let seeds = lifting.fallback_seeds(&mesh.positions, 2.0 * sampling.radius);
            add_orbits(&mut sampling, mesh, &resolved, &seeds)?;
            lifting = Lifting::new(mesh, &resolved, &sampling, &options.lift)?;
            progress.inc(1);
        }
        timings.lift_setup_ms = ms(t);
        progress.start("basis", 0);
        let t = Instant::now();
        let basis = SymmetricBasis::new(&sampling);
        let graph = SamplingGraph::new(&sampling.positions, sampling.radius)?;
        let plan = RotationPlan::new(&graph, &sampling)?;
        let mut delta = vec![[0.0; 3]; sampling.len()];
        graph.apply_laplacian(&sampling.positions, &mut delta);
        timings.basis_ms = ms(t);
        if lifting.fallback_vertices() > 0 && !resolved.symmetries.is_empty() {
            warnings.push(format!(
                "{} vertices have no symmetry-consistent sample within the Gaussian cut-off and follow their \
                 nearest samples (symmetry may not be exact there): sample more densely",
                lifting.fallback_vertices()
            ));
        }
        let stats = DeformStats {
            vertices: mesh.num_vertices(),
            diagonal: diag,
            samples: sampling.len(),
            orbits: sampling.orbits.len(),
            degenerate_orbits: sampling.degenerate_orbits(),
            dof: basis.dof(),
            radius: sampling.radius,
            graph_edges: graph.num_edges(),
            rotation_fits: plan.own_fits(),
            lift_nonzeros: lifting.nnz(),
            lift_rows: lifting.num_rows(),
            fallback_vertices: lifting.fallback_vertices(),
            symmetries: resolved.symmetries.len(),
            iterations: options.editing.iterations,
            timings,
            ..Default::default()
        };
        progress.finish();
        let workspace = Workspace::new(basis.dof(), sampling.len(), 0, None);
        let lift_work = vec![[0.0; 3]; lifting.num_rows()];
        Ok(DeformSession {
            rest: mesh.positions.clone(),
            mesh: mesh.clone(),
            resolved,
            sampling,
            basis,
            graph,
            plan,
            delta,
            lifting,
            options: options.clone(),
            system: None,
            workspace,
            positions: mesh.positions.clone(),
            lift_work,
            fits: Vec::new(),
            handle_vertices: Vec::new(),
            warnings,
            stats,
        })
    }

    /// Selects the handles' samples and factorises the reduced system (eq. 3.4) for them. The
    /// handles' own `transform`s are not used here (give them to [`DeformSession::solve`]).
    ///
    /// A sample belongs to a handle when its position lies in the handle's box or ball (enlarged
    /// by 10⁻⁹ × the diagonal), or — for `vertices` / `faces` regions — when its nearest mesh vertex
    /// is in the region; unions mix both rules per part. Errors: no handles
    /// ([`DeformError::NoHandles`]), a region selecting no vertex ([`DeformError::EmptyRegion`]),
    /// a handle selecting no sample ([`DeformError::HandleSelectsNoSample`]), two handles sharing
    /// a sample ([`DeformError::OverlappingHandles`]), an undetermined system
    /// ([`DeformError::Unconstrained`], only with `editing.regularization = 0`).
    pub fn set_handles(&mut self, handles: &[Handle]) -> Result<()> {
        let t = Instant::now();
        let (selected, handle_vertices) = select_handle_samples(
            &self.mesh,
            &self.sampling.positions,
            self.sampling.radius,
            handles,
            self.resolved.margin,
        )?;
        let seeds: Vec<Point3> = (0..self.sampling.len())
            .map(|i| self.sampling.positions[self.sampling.orbits[self.sampling.orbit_of[i] as usize].start])
            .collect();
        let system = HandleSystem::new(&self.graph, &self.basis, selected, &seeds, &self.options.editing)?;
        self.stats.handles = handles.len();
        self.stats.handle_samples = system.samples.iter().map(Vec::len).sum();
        self.stats.alpha = system.alpha;
        self.workspace = Workspace::new(self.basis.dof(), self.sampling.len(), handles.len(), Some(&system));
        self.stats.sparse_factor = system.is_sparse();
        self.fits = system
            .samples
            .iter()
            .enumerate()
            .map(|(h, s)| HandleFit { handle: h, samples: s.len(), max_error: 0.0, rms_error: 0.0 })
            .collect();
        self.system = Some(system);
        self.handle_vertices = handle_vertices;
        self.positions.copy_from_slice(&self.rest);
        self.stats.timings.prefactor_ms = ms(t);
        Ok(())
    }

    /// Solves one frame: `handle_transforms[h]` moves handle `h`'s rest positions. Runs the
    /// co-rotated iterations on the sampling, lifts the result and returns the deformed vertex
    /// positions. On error nothing is written: the previous positions stay.
    ///
    /// Allocation-free after [`DeformSession::set_handles`]: every buffer lives in the session
    /// (checked with a counting allocator over all threads: 0 allocations in 60 solves). One
    /// caveat is rayon's: its global job queue allocates a small block about every 63 parallel
    /// calls made from a thread outside the rayon pool (about once per 20 solves on a 22k-vertex
    /// mesh); calling `solve` from inside the pool (`rayon::scope`, `ThreadPool::install`) avoids
    /// even that.
    pub fn solve(&mut self, handle_transforms: &[Mat4]) -> Result<&[Point3]> {
        let sys = self.system.as_ref().ok_or(DeformError::HandlesNotSet)?;
        if handle_transforms.len() != sys.samples.len() {
            return Err(DeformError::TransformCount {
                expected: sys.samples.len(),
                found: handle_transforms.len(),
            });
        }
        for (h, m) in handle_transforms.iter().enumerate() {
            let affine = m[3] == [0.0, 0.0, 0.0, 1.0];
            if !affine || m.iter().flatten().any(|x| !x.is_finite()) {
                return Err(DeformError::InvalidTransform { handle: h });
            }
            let deviation = crate::mat3::rigidity_deviation(m);
            if deviation > HANDLE_RIGIDITY_TOLERANCE {
                return Err(DeformError::NonRigidTransform { handle: h, deviation });
            }
        }
        let t = Instant::now();
        solve_frame(
            sys,
            &self.graph,
            &self.plan,
            &self.sampling.frames,
            &self.basis,
            &self.sampling.positions,
            &self.delta,
            handle_transforms,
            self.options.editing.iterations,
            &mut self.workspace,
        );
        self.stats.timings.solve_ms = ms(t);
        let bound = 1e12 * self.stats.diagonal;
        if self.workspace.ubar.iter().flatten().any(|x| !x.is_finite() || x.abs() > bound) {
            return Err(DeformError::NonFinite);
        }
        let t = Instant::now();
        self.lifting.lift(&self.workspace.ubar, &self.rest, &mut self.lift_work, &mut self.positions);
        self.stats.timings.lift_ms = ms(t);
        let d = self.stats.diagonal;
        for (f, (m, s2)) in
            self.fits.iter_mut().zip(self.workspace.fit_max.iter().zip(&self.workspace.fit_sq))
        {
            f.max_error = m / d;
            f.rms_error = (s2 / f.samples.max(1) as f64).sqrt() / d;
        }
        Ok(&self.positions)
    }

    /// The deformed positions of the last successful solve (the rest positions before).
    pub fn positions(&self) -> &[Point3] {
        &self.positions
    }

    /// The rest positions.
    pub fn rest_positions(&self) -> &[Point3] {
        &self.rest
    }

    /// Displacements `ū` of the samples in the last solve.
    pub fn sample_displacements(&self) -> &[Point3] {
        &self.workspace.ubar
    }

    /// How closely each handle reached its target in the last solve.
    pub fn handle_fit(&self) -> &[HandleFit] {
        &self.fits
    }

    /// Per handle, the largest distance of its region's vertices in the last solve from where
    /// `handle_transforms` send their rest positions, relative to the diagonal. The handles
    /// constrain samples ([`DeformSession::handle_fit`]); the vertices between them follow the
    /// lifting, so this is what a user measures on the written mesh.
    pub fn handle_vertex_fit(&self, handle_transforms: &[Mat4]) -> Vec<f64> {
        let d = self.stats.diagonal;
        self.handle_vertices
            .iter()
            .zip(handle_transforms)
            .map(|(vs, m)| {
                vs.iter()
                    .map(|&v| {
                        let target = motif_core::geometry::transform_point(m, self.rest[v as usize]);
                        motif_core::geometry::dist(target, self.positions[v as usize])
                    })
                    .fold(0.0, f64::max)
                    / d
            })
            .collect()
    }

    /// Samples of each handle of the current handle set (empty before `set_handles`).
    pub fn handle_samples(&self) -> Vec<Vec<u32>> {
        self.system.as_ref().map(|s| s.samples.clone()).unwrap_or_default()
    }

    /// Sizes and timings.
    pub fn stats(&self) -> &DeformStats {
        &self.stats
    }

    /// The symmetric sampling.
    pub fn sampling(&self) -> &SymmetricSampling {
        &self.sampling
    }

    /// The basis `U`.
    pub fn basis(&self) -> &SymmetricBasis {
        &self.basis
    }

    /// The sampling graph.
    pub fn graph(&self) -> &SamplingGraph {
        &self.graph
    }

    /// Which samples take their co-rotation from their orbit's seed.
    pub fn rotation_plan(&self) -> &RotationPlan {
        &self.plan
    }

    /// The lifting matrix `W`.
    pub fn lifting(&self) -> &Lifting {
        &self.lifting
    }

    /// The resolved annotation (no symmetries with [`SymmetryMode::Ignore`]).
    pub fn annotation(&self) -> &ResolvedAnnotation {
        &self.resolved
    }

    /// Warnings: forced approximate symmetries, ignored entries, unsupported vertices.
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }

    /// The options the session was built with.
    pub fn options(&self) -> &DeformOptions {
        &self.options
    }
}

/// Checks that every element maps its region onto the shape within the tolerance.
fn validate_fit(
    mesh: &TriMesh,
    resolved: &ResolvedAnnotation,
    mode: AnnotationValidation,
    warnings: &mut Vec<String>,
) -> Result<()> {
    if resolved.symmetries.is_empty() {
        return Ok(());
    }
    let surface = SurfaceDistance::new(mesh)?;
    for e in resolved.elements() {
        let r = element_residual(mesh, &surface, &e);
        if r > resolved.tolerance {
            let err = DeformError::SymmetryMismatch {
                symmetry: e.name.clone(),
                transform: e.label.clone(),
                residual: r,
                tolerance: resolved.tolerance,
            };
            match mode {
                AnnotationValidation::Strict => return Err(err),
                AnnotationValidation::Force => warnings.push(format!("forced: {err}")),
            }
        }
    }
    Ok(())
}

/// The result of [`deform`].
#[derive(Debug, Clone, PartialEq)]
pub struct DeformResult {
    /// Deformed vertex positions, same order as the input mesh.
    pub positions: Vec<Point3>,
    /// Sizes and timings.
    pub stats: DeformStats,
    /// Handle fit errors.
    pub fit: Vec<HandleFit>,
    /// Warnings of the session.
    pub warnings: Vec<String>,
}

/// One-shot deformation: builds a session, sets the handles, solves for `transforms` (one per
/// handle; empty: each handle's own `transform`, identity when it has none).
pub fn deform(
    mesh: &TriMesh,
    annotation: &SymmetryAnnotation,
    handles: &[Handle],
    transforms: &[Mat4],
    options: &DeformOptions,
) -> Result<DeformResult> {
    let mut s = DeformSession::new(mesh, annotation, options)?;
    s.set_handles(handles)?;
    let own: Vec<Mat4>;
    let t = if transforms.is_empty() {
        own = handles.iter().map(Handle::transform_or_identity).collect();
        &own
    } else {
        transforms
    };
    let positions = s.solve(t)?.to_vec();
    Ok(DeformResult { positions, stats: s.stats.clone(), fit: s.fits.clone(), warnings: s.warnings.clone() })
}
