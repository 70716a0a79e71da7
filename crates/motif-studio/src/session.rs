//! One client's state and the operations on it. Every operation is a plain blocking function
//! that calls the library crates and returns the messages to send; the server runs them on
//! blocking threads. Nothing here is an algorithm of its own: models are read by `motif_core::io`,
//! symmetries come from `motif_deform::symmetry_detect` and `check_annotation`, deformation from
//! `DeformSession`, resizing from `motif_retarget`, detections from `motif_detect`.

use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Instant;

use motif_core::geometry::{IDENTITY4, Mat4, dot, norm, scale};
use motif_core::io::{Format, Model, WriteOptions};
use motif_core::procedural::{Region, SymmetryAnnotation};
use motif_core::progress::{NoProgress, Progress};
use motif_core::{Point3, TriMesh};
use motif_deform::symmetry_detect::{SymmetryDetectOptions, detect_symmetries_with_progress};
use motif_deform::{DeformOptions, DeformSession, Handle, SymmetryMaps, check_annotation};
use motif_detect::DetectionResult;
use motif_retarget::offsets::{OffsetOptions, Repetition, analyze_features, prepare_features};
use motif_retarget::retarget::{RetargetOptions, RetargetSession, orient_offsets};

use crate::cancel::JobProgress;
use crate::error::{Result, StudioError};
use crate::protocol::{
    BinaryKind, ClassSummary, ExportSource, FrameTiming, GroupSummary, HandleSpec, ServerMessage,
    encode_binary, encode_file,
};
use crate::sandbox::{Sandbox, shorten};

/// A message to send: JSON text or a binary geometry frame.
#[derive(Debug)]
pub enum Out {
    /// A JSON message.
    Text(ServerMessage),
    /// A binary message (see [`crate::protocol`]).
    Binary(Vec<u8>),
}

/// Most handles in one handle set, and balls in one handle.
const MAX_HANDLES: usize = 64;
const MAX_BALLS: usize = 256;

/// The opened model.
#[derive(Debug)]
pub struct Loaded {
    /// File or example name.
    pub name: String,
    /// The file it came from (canonical), if any.
    pub path: Option<PathBuf>,
    /// The model as read.
    pub model: Model,
    /// Its triangle mesh when it has triangles.
    pub mesh: Option<TriMesh>,
}

impl Loaded {
    fn mesh(&self) -> Result<&TriMesh> {
        self.mesh.as_ref().ok_or_else(|| {
            StudioError::NotReady(format!(
                "{} is a point cloud ({} points): this needs a triangle mesh",
                self.name,
                self.model.vertices.len()
            ))
        })
    }
}

struct DeformState {
    session: DeformSession,
    maps: Option<SymmetryMaps>,
    /// The current handle set and the target of each handle (last solved, or as set).
    specs: Vec<HandleSpec>,
    transforms: Vec<Mat4>,
    solved: bool,
    last_solve_ms: f64,
    /// The deformed mesh, for vertex normals (positions refreshed per frame that asks for them).
    normals_mesh: TriMesh,
}

struct RetargetState {
    session: RetargetSession,
    principal: Vec<Point3>,
    /// The last result, kept whole: its labels place each vertex on the input for the export's
    /// per-vertex data.
    last: Option<motif_retarget::retarget::Retargeted>,
    /// Open edges of the input, beside which the output's are reported.
    input_boundary: usize,
}

/// Counts live sessions; a session decrements it when it is dropped.
#[derive(Debug, Clone, Default)]
pub struct SessionCounter(Arc<AtomicUsize>);

impl SessionCounter {
    /// Live sessions.
    pub fn get(&self) -> usize {
        self.0.load(Ordering::SeqCst)
    }
}

struct CountGuard(SessionCounter);

impl Drop for CountGuard {
    fn drop(&mut self) {
        self.0.0.fetch_sub(1, Ordering::SeqCst);
    }
}

/// One client's state.
pub struct Session {
    sandbox: Arc<Sandbox>,
    seed: u64,
    inputs: Vec<PathBuf>,
    loaded: Option<Arc<Loaded>>,
    annotation: Option<SymmetryAnnotation>,
    deform: Option<DeformState>,
    retarget: Option<RetargetState>,
    /// The detections shown on the current model (detected or loaded), for `SaveDetections`.
    detections: Option<DetectionResult>,
    /// Bumped whenever the model or annotation changes, so a deformation session built without
    /// the lock is installed only if it still matches.
    generation: u64,
    _count: CountGuard,
}

/// A session behind a mutex, shared by the connection's tasks; locked only on blocking threads.
pub type Shared = Arc<Mutex<Session>>;

/// Locks a session; a poisoned lock (a bug in an earlier operation) is recovered, the state is
/// plain data.
pub fn lock(s: &Shared) -> MutexGuard<'_, Session> {
    s.lock().unwrap_or_else(|e| e.into_inner())
}

fn ms_since(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

impl Session {
    /// A new, empty session (counted in `counter` until dropped).
    pub fn new(sandbox: Arc<Sandbox>, seed: u64, counter: &SessionCounter) -> Session {
        counter.0.fetch_add(1, Ordering::SeqCst);
        Session {
            sandbox,
            seed,
            inputs: Vec::new(),
            loaded: None,
            annotation: None,
            deform: None,
            retarget: None,
            detections: None,
            generation: 0,
            _count: CountGuard(counter.clone()),
        }
    }

    fn loaded(&self) -> Result<Arc<Loaded>> {
        self.loaded.clone().ok_or_else(|| StudioError::NotReady("open a model first".to_string()))
    }
}

fn model_messages(l: &Loaded, annotation: Option<&SymmetryAnnotation>) -> Vec<Out> {
    let v = &l.model.vertices;
    let bb = v.aabb();
    let bbox = bb.map(|b| [b.min, b.max]).unwrap_or([[0.0; 3]; 2]);
    vec![
        Out::Text(ServerMessage::Model {
            name: l.name.clone(),
            vertices: v.len(),
            triangles: l.model.triangles.len(),
            bbox,
            diagonal: v.diagonal(),
            annotation: annotation.cloned(),
            warnings: l.model.warnings.clone(),
        }),
        Out::Binary(encode_binary(
            BinaryKind::Model,
            0,
            &v.positions,
            None,
            &l.model.triangles,
            FrameTiming::default(),
        )),
    ]
}

fn install(
    shared: &Shared,
    p: &JobProgress,
    loaded: Loaded,
    annotation: Option<SymmetryAnnotation>,
    input: Vec<PathBuf>,
) -> Vec<Out> {
    p.check();
    let mut s = lock(shared);
    let out = model_messages(&loaded, annotation.as_ref());
    s.inputs.extend(input);
    s.loaded = Some(Arc::new(loaded));
    s.annotation = annotation;
    s.deform = None;
    s.retarget = None;
    s.detections = None;
    s.generation += 1;
    out
}

fn loaded_from(name: String, path: Option<PathBuf>, model: Model) -> Loaded {
    let mesh = model.is_mesh().then(|| model.mesh());
    Loaded { name, path, model, mesh }
}

/// Opens a model file under the root; `STEM.sym.json` beside it is loaded as its annotation.
pub fn open(shared: &Shared, path: &str, p: &JobProgress) -> Result<Vec<Out>> {
    let sandbox = lock(shared).sandbox.clone();
    let file = sandbox.resolve_read(path)?;
    p.stage("reading");
    let model = motif_core::io::read(&file)?;
    let mut inputs = vec![file.clone()];
    let sidecar = file.with_extension("sym.json");
    let mut loaded = loaded_from(sandbox.display(&file), Some(file), model);
    // The annotation beside the model is checked as a loaded one is; one that cannot be read or
    // does not fit (left from an earlier version of the file) is not loaded, and the model opens
    // with a warning saying why, rather than failing to open or failing at the first click.
    let mut annotation = None;
    if let (true, Some(mesh)) = (sidecar.is_file(), &loaded.mesh) {
        let name = sandbox.display(&sidecar);
        let checked = sandbox
            .resolve_read(&sidecar.display().to_string())
            .map_err(|e| e.to_string())
            .and_then(|sidecar| {
                let a = motif_deform::read_annotation(&sidecar).map_err(|e| e.to_string())?;
                let report = check_annotation(mesh, &a).map_err(|e| e.to_string())?;
                match misfits(&report, &a) {
                    None => Ok((sidecar, a)),
                    Some(problems) => Err(format!("it does not fit this model: {problems}")),
                }
            });
        match checked {
            Ok((sidecar, a)) => {
                inputs.push(sidecar);
                annotation = Some(a);
            }
            Err(why) => loaded.model.warnings.push(format!("{name} was not loaded: {why}")),
        }
    }
    Ok(install(shared, p, loaded, annotation, inputs))
}

/// Opens a generated example with its known symmetry annotation.
pub fn example(shared: &Shared, name: &str, p: &JobProgress) -> Result<Vec<Out>> {
    let seed = lock(shared).seed;
    p.stage("generating");
    let ex = motif_core::procedural::generate(name, seed)?;
    let annotation = (!ex.structure.symmetry.symmetries.is_empty()).then(|| ex.structure.symmetry.clone());
    let loaded = loaded_from(ex.name.clone(), None, Model::from_mesh(&ex.mesh));
    Ok(install(shared, p, loaded, annotation, Vec::new()))
}

/// Opens an uploaded file (format from the name's extension; nothing is written to disk).
pub fn upload(shared: &Shared, name: &str, bytes: &[u8], p: &JobProgress) -> Result<Vec<Out>> {
    let file_name =
        std::path::Path::new(name).file_name().map(|n| n.to_string_lossy().to_string()).unwrap_or_default();
    let format = Format::from_path(std::path::Path::new(&file_name))?;
    if matches!(format, Format::Gltf) {
        return Err(StudioError::BadMessage(
            "a .gltf upload cannot bring its external buffers: upload a .glb instead".to_string(),
        ));
    }
    p.stage("reading");
    let model = motif_core::io::read_from_bytes(bytes, format, std::path::Path::new(&file_name))?;
    let loaded = loaded_from(file_name, None, model);
    Ok(install(shared, p, loaded, None, Vec::new()))
}

/// The annotation message, from the annotation's check against the mesh (`check_annotation`).
fn annotation_message(
    report: &motif_deform::AnnotationReport,
    annotation: &SymmetryAnnotation,
    groups: Vec<GroupSummary>,
    t: Instant,
) -> Result<ServerMessage> {
    let max_residual = report.symmetries.iter().map(|s| s.max_residual).fold(0.0, f64::max);
    Ok(ServerMessage::Annotation {
        annotation: annotation.clone(),
        groups,
        max_residual,
        ok: report.ok,
        ms: ms_since(t),
    })
}

fn set_annotation(shared: &Shared, p: &JobProgress, annotation: SymmetryAnnotation, input: Option<PathBuf>) {
    p.check();
    let mut s = lock(shared);
    s.annotation = Some(annotation);
    s.inputs.extend(input);
    s.deform = None;
    s.generation += 1;
}

/// Detects global and partial symmetries of the current mesh.
pub fn detect_symmetry(shared: &Shared, p: &JobProgress) -> Result<Vec<Out>> {
    let (loaded, seed) = {
        let s = lock(shared);
        (s.loaded()?, s.seed)
    };
    let mesh = loaded.mesh()?;
    let t = Instant::now();
    let options = SymmetryDetectOptions { seed, ..Default::default() };
    let det = detect_symmetries_with_progress(mesh, &options, p)?;
    let groups = det
        .report
        .groups
        .iter()
        .map(|g| GroupSummary {
            name: g.name.clone(),
            schoenflies: g.structure.schoenflies.clone(),
            order: g.structure.order,
            max_residual: g.max_residual,
        })
        .collect();
    let report = check_annotation(mesh, &det.annotation)?;
    let msg = annotation_message(&report, &det.annotation, groups, t)?;
    set_annotation(shared, p, det.annotation, None);
    Ok(vec![Out::Text(msg)])
}

/// What does not fit when an annotation's check against the mesh failed (`None` when it fits).
fn misfits(report: &motif_deform::AnnotationReport, annotation: &SymmetryAnnotation) -> Option<String> {
    if report.ok {
        return None;
    }
    let problems: Vec<String> = report
        .symmetries
        .iter()
        .filter(|c| !c.ok)
        .map(|c| match &c.problem {
            Some(problem) => format!("symmetry {:?}: {problem}", c.name),
            None => format!(
                "symmetry {:?} moves the surface {:.1e} of the diagonal off itself (tolerance {:.0e})",
                c.name, c.max_residual, annotation.tolerance
            ),
        })
        .collect();
    Some(if problems.is_empty() { "the check failed".to_string() } else { problems.join("; ") })
}

/// Loads a `motif_symmetry_v1` annotation and checks it against the mesh.
pub fn load_annotation(shared: &Shared, path: &str, p: &JobProgress) -> Result<Vec<Out>> {
    let (loaded, sandbox) = {
        let s = lock(shared);
        (s.loaded()?, s.sandbox.clone())
    };
    let mesh = loaded.mesh()?;
    let file = sandbox.resolve_read(path)?;
    let t = Instant::now();
    let annotation = motif_deform::read_annotation(&file)?;
    // An annotation that does not fit the open model (another model's, or an empty region)
    // could only fail later, at the first click: refused here, with what does not fit.
    let report = check_annotation(mesh, &annotation)?;
    if let Some(problems) = misfits(&report, &annotation) {
        return Err(StudioError::BadPath {
            path: shorten(path),
            problem: format!("does not fit the open model, so it was not loaded: {problems}"),
        });
    }
    let msg = annotation_message(&report, &annotation, Vec::new(), t)?;
    set_annotation(shared, p, annotation, Some(file));
    Ok(vec![Out::Text(msg)])
}

fn write_json_atomic(path: &std::path::Path, value: &impl serde::Serialize) -> Result<()> {
    let text = serde_json::to_string_pretty(value)
        .map_err(|e| StudioError::Internal(format!("serialising {}: {e}", path.display())))?;
    motif_core::io::write_atomic(path, |w| w.write_all(text.as_bytes()))?;
    Ok(())
}

/// Held from the "already exists" check to the last file written by an export or a save, so
/// that two sessions writing one new name cannot both be told "saved" (each session has a lock
/// of its own; without this, eight sessions exporting `race.ply` at once got up to five "saved"
/// replies, and a model beside another session's annotation).
static WRITES: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn writes_lock() -> std::sync::MutexGuard<'static, ()> {
    WRITES.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

fn check_fresh(path: &std::path::Path, given: &str, overwrite: bool) -> Result<()> {
    if !overwrite && path.exists() {
        return Err(StudioError::BadPath {
            path: shorten(given),
            problem: "already exists (choose another name, or tick \"replace existing files\")".to_string(),
        });
    }
    Ok(())
}

/// Saves the current annotation.
pub fn save_annotation(shared: &Shared, path: &str, overwrite: bool) -> Result<Vec<Out>> {
    let s = lock(shared);
    let annotation = s
        .annotation
        .as_ref()
        .ok_or_else(|| StudioError::NotReady("no annotation yet: detect or load one".to_string()))?;
    save_json_document(&s, path, overwrite, "an annotation", "model.sym.json", |file| {
        write_json_atomic(file, annotation)
    })
}

/// Writes a JSON document under the root for the save requests: the name must end in .json
/// (`what` and `example` say what it is), inputs are never replaced and an existing file only
/// with `overwrite`.
fn save_json_document(
    s: &Session,
    path: &str,
    overwrite: bool,
    what: &str,
    example: &str,
    write: impl FnOnce(&std::path::Path) -> Result<()>,
) -> Result<Vec<Out>> {
    if !path.to_ascii_lowercase().ends_with(".json") {
        return Err(StudioError::BadPath {
            path: shorten(path),
            problem: format!("{what} is a JSON document: name it .json (e.g. {example})"),
        });
    }
    let _writes = writes_lock();
    let file = s.sandbox.resolve_write(path, &s.inputs)?;
    check_fresh(&file, path, overwrite)?;
    write(&file)?;
    Ok(vec![Out::Text(ServerMessage::Saved { paths: vec![s.sandbox.display(&file)], notes: Vec::new() })])
}

fn handle_regions(handles: &[HandleSpec]) -> Result<Vec<Handle>> {
    if handles.len() > MAX_HANDLES {
        return Err(StudioError::BadMessage(format!("{} handles: at most {MAX_HANDLES}", handles.len())));
    }
    handles
        .iter()
        .enumerate()
        .map(|(i, h)| {
            if h.balls.is_empty() || h.balls.len() > MAX_BALLS {
                return Err(StudioError::BadMessage(format!(
                    "handle {i}: needs 1 to {MAX_BALLS} balls, has {}",
                    h.balls.len()
                )));
            }
            if h.balls
                .iter()
                .any(|b| !(b.radius > 0.0 && b.radius.is_finite()) || b.center.iter().any(|c| !c.is_finite()))
            {
                return Err(StudioError::BadMessage(format!(
                    "handle {i}: centres must be finite, radii positive"
                )));
            }
            let mut regions: Vec<Region> =
                h.balls.iter().map(|b| Region::Sphere { center: b.center, radius: b.radius }).collect();
            let region = if regions.len() == 1 { regions.remove(0) } else { Region::Union(regions) };
            Ok(Handle::fixed(region))
        })
        .collect()
}

/// The target of each handle of a new set: given by the client; else the current target of an
/// equal handle of the previous set; else the rigid motion that best fits the region's vertices
/// from the rest shape to the current shape (`motif_core::icp::fit_rigid`), so a handle added
/// after a drag holds the part it grabs where it is instead of pulling it back to rest.
fn handle_targets(
    d: &DeformState,
    mesh: &TriMesh,
    handles: &[HandleSpec],
    regions: &[Handle],
    given: &[Option<Mat4>],
) -> Vec<Mat4> {
    let current = if d.solved { d.session.positions() } else { d.session.rest_positions() };
    let tolerance = 1e-9 * d.session.stats().diagonal;
    let mut used = vec![false; d.specs.len()];
    handles
        .iter()
        .zip(regions)
        .enumerate()
        .map(|(i, (spec, region))| {
            if let Some(Some(m)) = given.get(i) {
                return *m;
            }
            if let Some(j) = (0..d.specs.len()).find(|&j| !used[j] && d.specs[j] == *spec) {
                used[j] = true;
                if let Some(m) = d.transforms.get(j) {
                    return *m;
                }
            }
            let vertices = region.region.vertex_indices(mesh, tolerance);
            let rest: Vec<Point3> = vertices.iter().map(|&v| mesh.positions[v]).collect();
            let now: Vec<Point3> = vertices.iter().map(|&v| current[v]).collect();
            if rest == now {
                return IDENTITY4; // exactly, not a fit's rounding
            }
            motif_core::icp::fit_rigid(&rest, &now).unwrap_or(IDENTITY4)
        })
        .collect()
}

/// Chooses the handle set: builds the deformation session on first use (sampling, basis, lift;
/// cancellable through `p`, without holding the session's lock), then factorises for these
/// handles and solves once for their targets (see [`ClientMessage::SetHandles`]), so the shape
/// stays as it was. An empty set returns to the rest shape.
///
/// [`ClientMessage::SetHandles`]: crate::protocol::ClientMessage::SetHandles
pub fn set_handles(
    shared: &Shared,
    handles: &[HandleSpec],
    given: &[Option<Mat4>],
    p: &JobProgress,
) -> Result<Vec<Out>> {
    let regions = handle_regions(handles)?;
    if given.len() > handles.len() {
        return Err(StudioError::BadMessage(format!(
            "{} transforms for {} handles",
            given.len(),
            handles.len()
        )));
    }
    if regions.is_empty() {
        let mut s = lock(shared);
        if let Some(d) = s.deform.as_mut() {
            d.solved = false;
            d.specs.clear();
            d.transforms.clear();
        }
        return Ok(Vec::new());
    }
    let (loaded, annotation, seed, generation, built) = {
        let s = lock(shared);
        (s.loaded()?, s.annotation.clone(), s.seed, s.generation, s.deform.is_some())
    };
    let mesh = loaded.mesh()?;
    let mut session_ms = 0.0;
    if !built {
        // Seconds on a 100k-vertex mesh: built outside the lock, stoppable at each stage.
        let t = Instant::now();
        let mut options = DeformOptions::default();
        options.sampling.seed = seed;
        let session = DeformSession::with_progress(mesh, &annotation.unwrap_or_default(), &options, p)?;
        session_ms = ms_since(t);
        p.check();
        let mut s = lock(shared);
        if s.generation != generation {
            return Err(StudioError::NotReady(
                "the model or annotation changed while the deformation session was built: pick the handles again"
                    .to_string(),
            ));
        }
        if s.deform.is_none() {
            s.deform = Some(DeformState {
                session,
                maps: None,
                specs: Vec::new(),
                transforms: Vec::new(),
                solved: false,
                last_solve_ms: 0.0,
                normals_mesh: mesh.clone(),
            });
        }
    }
    p.check();
    let mut s = lock(shared);
    if s.generation != generation {
        return Err(StudioError::NotReady("the model changed: pick the handles again".to_string()));
    }
    let Some(d) = s.deform.as_mut() else { return Err(StudioError::Internal("set_handles".to_string())) };
    let targets = handle_targets(d, mesh, handles, &regions, given);
    d.session.set_handles(&regions).inspect_err(|_| {
        d.solved = false;
        d.specs.clear();
        d.transforms.clear();
    })?;
    d.specs = handles.to_vec();
    d.transforms = targets.clone();
    d.solved = false;
    let st = d.session.stats();
    let samples = d.session.handle_samples().iter().map(Vec::len).collect();
    let reply = Out::Text(ServerMessage::Handles {
        handles: regions.len(),
        samples,
        total_samples: st.samples,
        dof: st.dof,
        prefactor_ms: st.timings.prefactor_ms,
        session_ms,
        transforms: targets.clone(),
    });
    let frame = solve_frame(d, 0, &targets, false, FrameTiming::default())?;
    Ok(vec![reply, Out::Binary(frame)])
}

/// Solves for `transforms` and encodes the frame (with vertex normals when asked).
fn solve_frame(
    d: &mut DeformState,
    seq: u32,
    transforms: &[Mat4],
    normals: bool,
    mut timing: FrameTiming,
) -> Result<Vec<u8>> {
    let t = Instant::now();
    d.session.solve(transforms)?;
    let solve_ms = ms_since(t);
    d.solved = true;
    d.last_solve_ms = solve_ms;
    d.transforms = transforms.to_vec();
    timing.solve_ms = solve_ms as f32;
    let positions = d.session.positions();
    let normals = if normals {
        d.normals_mesh.positions.copy_from_slice(positions);
        Some(d.normals_mesh.vertex_normals())
    } else {
        None
    };
    Ok(encode_binary(BinaryKind::DeformFrame, seq, positions, normals.as_deref(), &[], timing))
}

/// Solves one drag frame and encodes the deformed positions. `received` is when the request
/// arrived (for the frame's timing fields).
pub fn drag(
    shared: &Shared,
    seq: u32,
    transforms: &[Mat4],
    normals: bool,
    received: (Instant, f64),
) -> Result<Vec<Out>> {
    let mut s = lock(shared);
    let d = s
        .deform
        .as_mut()
        .filter(|d| !d.specs.is_empty())
        .ok_or_else(|| StudioError::NotReady("pick handles before dragging".to_string()))?;
    let timing =
        FrameTiming { queue_ms: ms_since(received.0) as f32, received_at: received.1, solve_ms: 0.0 };
    Ok(vec![Out::Binary(solve_frame(d, seq, transforms, normals, timing)?)])
}

/// Measures the current deformation: symmetry residual (eq. 3.2) and handle fit.
pub fn release(shared: &Shared) -> Result<Vec<Out>> {
    let mut s = lock(shared);
    let loaded = s.loaded()?;
    let annotation = s.annotation.clone();
    let Some(d) = s.deform.as_mut() else { return Ok(Vec::new()) };
    let mesh = loaded.mesh()?;
    if d.maps.is_none() {
        if let Some(a) = annotation.as_ref().filter(|a| !a.symmetries.is_empty()) {
            d.maps = Some(SymmetryMaps::new(mesh, a)?);
        }
    }
    let positions = if d.solved { d.session.positions() } else { d.session.rest_positions() };
    let (residual, rest_residual) = match &d.maps {
        Some(m) => {
            let r = m.residual(positions)?;
            (Some(r.max), Some(r.rest_max))
        }
        None => (None, None),
    };
    let handle_error =
        if d.solved { d.session.handle_fit().iter().map(|f| f.max_error).fold(0.0, f64::max) } else { 0.0 };
    Ok(vec![Out::Text(ServerMessage::Deformed {
        residual,
        rest_residual,
        handle_error,
        solve_ms: d.last_solve_ms,
    })])
}

/// Writes the deformed (or retargeted) model and, for the deformed one, its annotation as
/// `STEM.sym.json`.
pub fn export(
    shared: &Shared,
    path: &str,
    source: ExportSource,
    overwrite: bool,
    download: bool,
) -> Result<Vec<Out>> {
    let s = lock(shared);
    let loaded = s.loaded()?;
    // Nothing to export says so before the file name is looked at (it used to say the default
    // name "already exists").
    if source == ExportSource::Retargeted && s.retarget.as_ref().and_then(|r| r.last.as_ref()).is_none() {
        return Err(StudioError::NotReady(
            "nothing resized yet: move a slider under Resize first (after Find offsets)".to_string(),
        ));
    }
    let writes = writes_lock();
    let file = s.sandbox.resolve_write(path, &s.inputs)?;
    check_fresh(&file, path, overwrite)?;
    Format::from_path(&file)?;
    let mut written = Vec::new();
    let mut notes = Vec::new();
    match source {
        ExportSource::Deformed => {
            let deformed = matches!((&s.deform, &loaded.mesh), (Some(d), Some(_)) if d.solved);
            let model = match (&s.deform, &loaded.mesh) {
                (Some(d), Some(mesh)) if d.solved => {
                    deformed_with_vertex_data(&loaded.model, d.session.positions().to_vec(), &mesh.triangles)
                }
                _ => loaded.model.clone(),
            };
            // A deformed model's annotation names its regions by the vertices they hold on the
            // rest shape: its boxes and spheres no longer hold the moved parts, and the export
            // could not be opened with its annotation again. STL keeps no vertex order (its
            // reader welds corners), so a deformed STL goes without it, and says so.
            let stl = Format::from_path(&file)? == Format::Stl;
            let annotation = match (s.annotation.as_ref().filter(|_| model.is_mesh()), &loaded.mesh) {
                (Some(_), Some(_)) if deformed && stl => {
                    notes.push(format!(
                        "{}: the annotation is not written beside a deformed STL (STL keeps no vertex \
                         order, which the deformed model's regions are named by); export OBJ, PLY, \
                         OFF or GLB to keep it",
                        s.sandbox.display(&file)
                    ));
                    None
                }
                (Some(a), Some(rest)) if deformed => Some(motif_deform::regions_as_vertices(a, rest)?),
                (a, _) => a.cloned(),
            };
            // The annotation goes beside the model as STEM.sym.json. Its path is checked before
            // anything is written, so that a refused annotation leaves no model behind. When that
            // file already holds the same annotation (the annotation this session read, or the
            // model exported to another format beside it), it is kept as it is.
            let mut side_to_write = None;
            if let Some(a) = annotation.as_ref() {
                let side_text = file.with_extension("sym.json").display().to_string();
                match s.sandbox.resolve_write(&side_text, &s.inputs) {
                    // A file there that already holds this annotation (the model exported to
                    // another format beside it) is kept as it is.
                    Ok(side)
                        if !overwrite
                            && motif_deform::read_annotation(&side).is_ok_and(|held| &held == a) => {}
                    Ok(side) => {
                        check_fresh(&side, &side_text, overwrite)?;
                        side_to_write = Some((side, a));
                    }
                    Err(e) => {
                        let same = s
                            .sandbox
                            .resolve_read(&side_text)
                            .ok()
                            .filter(|p| s.inputs.contains(p))
                            .and_then(|p| motif_deform::read_annotation(&p).ok())
                            .is_some_and(|held| &held == a);
                        if !same {
                            return Err(e);
                        }
                    }
                }
            }
            motif_core::io::write(&file, &model, &WriteOptions::default())?;
            written.push(s.sandbox.display(&file));
            if let Some((side, a)) = side_to_write {
                write_json_atomic(&side, a)?;
                written.push(s.sandbox.display(&side));
            }
        }
        ExportSource::Retargeted => {
            let (r, res) = s
                .retarget
                .as_ref()
                .and_then(|r| r.last.as_ref().map(|last| (r, last)))
                .ok_or_else(|| StudioError::NotReady("nothing resized yet".to_string()))?;
            let model = with_vertex_data(&loaded.model, &res.mesh, || r.session.vertex_origins(res));
            motif_core::io::write(&file, &model, &WriteOptions::default())?;
            written.push(s.sandbox.display(&file));
        }
    }
    let mut out = Vec::new();
    if download {
        // The bytes just written, read back through the sandbox, for the browser to save.
        for w in &written {
            let f = s.sandbox.resolve_read(w)?;
            let bytes = std::fs::read(&f)
                .map_err(|source| StudioError::Io { what: format!("reading {w}"), source })?;
            let name = f.file_name().map(|n| n.to_string_lossy().to_string()).unwrap_or_else(|| w.clone());
            out.push(Out::Binary(encode_file(&name, &bytes)));
        }
    }
    // Read back before the lock goes, so that another session cannot have replaced the files.
    drop(writes);
    out.insert(0, Out::Text(ServerMessage::Saved { paths: written, notes }));
    Ok(out)
}

/// The retargeted `out` with the per-vertex data (normals, colours, attributes) of the model it
/// was resized from, carried by `origins` ([`motif_retarget::retarget::carry_vertex_data`]); just
/// the mesh when the model has none.
fn with_vertex_data(
    model: &Model,
    out: &TriMesh,
    origins: impl FnOnce() -> Vec<Option<motif_retarget::retarget::VertexOrigin>>,
) -> Model {
    let v = &model.vertices;
    if v.normals.is_none() && v.colors.is_none() && v.attributes.is_empty() {
        return Model::from_mesh(out);
    }
    let cloud = motif_retarget::retarget::carry_vertex_data(v, &model.triangles, out, &origins());
    Model { vertices: cloud, ..Model::from_mesh(out) }
}

/// The deformed model: the rest model's colours and attributes on the moved vertices (one to
/// one), and normals computed anew when it had some (the deformation turns the surface).
fn deformed_with_vertex_data(model: &Model, positions: Vec<Point3>, triangles: &[[u32; 3]]) -> Model {
    let mesh = TriMesh { positions, triangles: triangles.to_vec() };
    let v = &model.vertices;
    let normals = v.normals.as_ref().map(|_| mesh.vertex_normals());
    let vertices = motif_core::point_cloud::PointCloud {
        positions: mesh.positions.clone(),
        normals,
        colors: v.colors.clone(),
        attributes: v.attributes.clone(),
    };
    Model { vertices, ..Model::from_mesh(&mesh) }
}

/// Whole cells of `mesh` along each offset: the extent along the offset's direction divided by
/// its length, rounded down (a readout for the page; 1e-6 absorbs rounding).
pub fn cells_along(mesh: &TriMesh, offsets: &[Point3]) -> Vec<usize> {
    offsets
        .iter()
        .map(|o| {
            let len = norm(*o);
            if len.is_nan() || len <= 0.0 {
                return 0;
            }
            let d = scale(*o, 1.0 / len);
            let (lo, hi) = mesh
                .positions
                .iter()
                .map(|p| dot(*p, d))
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), t| (lo.min(t), hi.max(t)));
            ((hi - lo) / len + 1e-6).floor().max(0.0) as usize
        })
        .collect()
}

/// Principal offsets of the current mesh, then the retargeting precomputation for them.
pub fn offsets(shared: &Shared, p: &JobProgress) -> Result<Vec<Out>> {
    let (loaded, seed) = {
        let s = lock(shared);
        (s.loaded()?, s.seed)
    };
    let mesh = loaded.mesh()?;
    let t = Instant::now();
    let offset_options = OffsetOptions { seed, ..Default::default() };
    let features = prepare_features(mesh, &offset_options, p)?;
    let analysis = analyze_features(&features, &offset_options, p)?;
    let principal = orient_offsets(&analysis.principal.iter().map(|o| o.offset_model).collect::<Vec<_>>());
    let summary = analysis.repetition.summary.clone();
    if analysis.repetition.kind == Repetition::NoRepetition || principal.is_empty() {
        p.check();
        lock(shared).retarget = None;
        return Ok(vec![Out::Text(ServerMessage::Offsets {
            principal: Vec::new(),
            cells: Vec::new(),
            min_steps: Vec::new(),
            summary,
            ms: ms_since(t),
        })]);
    }
    let options = RetargetOptions { seed, ..Default::default() };
    let session = RetargetSession::with_features(mesh, &features, &principal, &options, p)?;
    let cells = cells_along(mesh, &principal);
    let min_steps = session.min_steps()[..principal.len().min(3)].to_vec();
    p.check();
    let input_boundary = mesh.edge_stats().boundary;
    lock(shared).retarget =
        Some(RetargetState { session, principal: principal.clone(), last: None, input_boundary });
    Ok(vec![Out::Text(ServerMessage::Offsets { principal, cells, min_steps, summary, ms: ms_since(t) })])
}

/// Resizes by `steps` principal offsets.
pub fn retarget(shared: &Shared, seq: u32, steps: [i32; 3]) -> Result<Vec<Out>> {
    let mut s = lock(shared);
    let r = s
        .retarget
        .as_mut()
        .ok_or_else(|| StudioError::NotReady("find the principal offsets first".to_string()))?;
    if steps.iter().any(|k| k.abs() > 64) {
        return Err(StudioError::BadMessage("steps: at most 64 cells either way".to_string()));
    }
    let t = Instant::now();
    let res = r.session.retarget(steps, &NoProgress)?;
    let ms = ms_since(t);
    let cells = cells_along(&res.mesh, &r.principal);
    let total_cells = cells.iter().product();
    // A stitching with seams of infinite cost must not look like a success (the CLI says the
    // same on stderr, and its --preview in red).
    let rep = &res.report;
    let warning = (rep.infinite_seams > 0).then(|| {
        // Nearby steps that do stitch cleanly (a few more solves, milliseconds each).
        let n = r.principal.len().clamp(1, 3);
        let others: Vec<String> = r
            .session
            .clean_alternatives(steps)
            .iter()
            .map(|s| format!("steps {}", s[..n].iter().map(i32::to_string).collect::<Vec<_>>().join(", ")))
            .collect();
        let others = match others.len() {
            0 => String::new(),
            1 => format!("; {} stitches cleanly", others[0]),
            _ => format!("; {} stitch cleanly", others.join(" and ")),
        };
        format!(
            "no seam-consistent stitching for these steps: at {} of {} seams one copy meets empty space in \
             another; {}{others}",
            rep.infinite_seams,
            rep.seams,
            motif_retarget::retarget::open_edges_after(rep.output_boundary_edges, r.input_boundary)
        )
    });
    let out = vec![
        Out::Text(ServerMessage::Retargeted {
            seq,
            steps,
            cells,
            total_cells,
            vertices: res.mesh.num_vertices(),
            triangles: res.mesh.num_triangles(),
            ms,
            warning,
        }),
        Out::Binary(encode_binary(
            BinaryKind::Retargeted,
            seq,
            &res.mesh.positions,
            None,
            &res.mesh.triangles,
            FrameTiming { solve_ms: ms as f32, ..Default::default() },
        )),
    ];
    r.last = Some(res);
    Ok(out)
}

/// The detections message for a result on the current model: boxes per class and, per vertex,
/// the class whose instance lists it (`points`) or whose box holds it; first class wins.
fn detections_message(loaded: &Loaded, result: &DetectionResult) -> ServerMessage {
    let positions = &loaded.model.vertices.positions;
    let mut point_class = vec![-1i32; positions.len()];
    let mut classes = Vec::new();
    for (j, c) in result.classes.iter().enumerate() {
        let mut count = 0;
        for inst in &c.instances {
            let mut mark = |i: usize, count: &mut usize| {
                if point_class[i] < 0 {
                    point_class[i] = j as i32;
                    *count += 1;
                }
            };
            match &inst.points {
                Some(pts) => pts
                    .iter()
                    .filter(|&&i| (i as usize) < positions.len())
                    .for_each(|&i| mark(i as usize, &mut count)),
                None => {
                    for (i, p) in positions.iter().enumerate() {
                        if (0..3).all(|k| p[k] >= inst.bbox_min[k] && p[k] <= inst.bbox_max[k]) {
                            mark(i, &mut count);
                        }
                    }
                }
            }
        }
        classes.push(ClassSummary {
            name: c.name.clone().unwrap_or_else(|| format!("class_{j}")),
            boxes: c.instances.iter().map(|i| [i.bbox_min, i.bbox_max]).collect(),
            points: count,
        });
    }
    ServerMessage::Detections { scene: result.scene.clone(), classes, point_class }
}

/// Loads a detection result (`../shared/formats/detection.md`) to show on the current model.
pub fn load_detections(shared: &Shared, path: &str) -> Result<Vec<Out>> {
    let (loaded, sandbox) = {
        let s = lock(shared);
        (s.loaded()?, s.sandbox.clone())
    };
    let file = sandbox.resolve_read(path)?;
    let result = DetectionResult::read(&file)?;
    result.validate(&file.display().to_string())?;
    let msg = detections_message(&loaded, &result);
    keep_detections(shared, &loaded, result, Some(file));
    Ok(vec![Out::Text(msg)])
}

/// Keeps `result` as the current model's detections, unless another model opened meanwhile;
/// the file it was read from becomes an input (never replaced).
fn keep_detections(shared: &Shared, loaded: &Arc<Loaded>, result: DetectionResult, input: Option<PathBuf>) {
    let mut s = lock(shared);
    if s.loaded.as_ref().is_some_and(|l| Arc::ptr_eq(l, loaded)) {
        s.detections = Some(result);
        s.inputs.extend(input);
    }
}

/// The model files and JSON documents under the root.
pub fn list_files(shared: &Shared) -> Result<Vec<Out>> {
    let sandbox = lock(shared).sandbox.clone();
    let (files, truncated) = sandbox.list(|p| {
        Format::from_path(p).is_ok() || p.extension().is_some_and(|e| e.eq_ignore_ascii_case("json"))
    });
    let (mut models, mut json) = (Vec::new(), Vec::new());
    for f in files {
        let text = f.display().to_string();
        if Format::from_path(&f).is_ok() { models.push(text) } else { json.push(text) }
    }
    Ok(vec![Out::Text(ServerMessage::Files { models, json, truncated })])
}

/// Writes the current detections as a detection result JSON under the root.
pub fn save_detections(shared: &Shared, path: &str, overwrite: bool) -> Result<Vec<Out>> {
    let s = lock(shared);
    let result = s
        .detections
        .as_ref()
        .ok_or_else(|| StudioError::NotReady("no detections yet: detect or load them".to_string()))?;
    save_json_document(&s, path, overwrite, "a detection result", "model.detect.json", |file| {
        Ok(result.write(file)?)
    })
}

/// Building-block detection of a model (`motif_detect`, thesis chapter 5): the one place the
/// detection pipeline is called from. Meshes are sampled on their surface by
/// [`motif_detect::detect_mesh`], whose instance point lists name the mesh's vertices.
pub fn detect_building_blocks(
    model: &Model,
    name: &str,
    seed: u64,
    progress: &dyn Progress,
) -> Result<DetectionResult> {
    let options = motif_detect::DetectOptions { seed, ..Default::default() };
    if model.is_mesh() {
        Ok(motif_detect::detect_mesh(&model.mesh(), name, &options, progress, false)?.result)
    } else {
        // Zero normals (NaN ones read as zero) are estimated from the points around them (all of
        // them, as for a cloud without normals, when more than half are zero).
        let mut cloud = model.vertices.clone();
        cloud.repair_degenerate_normals();
        Ok(motif_detect::detect(&cloud, name, &options, progress, false)?.result)
    }
}

/// Runs building-block detection on the current model and shows the result.
pub fn detect(shared: &Shared, p: &JobProgress) -> Result<Vec<Out>> {
    let (loaded, seed) = {
        let s = lock(shared);
        (s.loaded()?, s.seed)
    };
    let result = detect_building_blocks(&loaded.model, &loaded.name, seed, p)?;
    p.check();
    let msg = detections_message(&loaded, &result);
    keep_detections(shared, &loaded, result, None);
    Ok(vec![Out::Text(msg)])
}
