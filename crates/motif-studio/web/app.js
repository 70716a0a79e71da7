// Motif studio page: a thin view over the server's WebSocket API (see crates/motif-studio/src/
// protocol.rs). Geometry comes from the server; the page only draws, picks and sends requests.
// `window.motif.state` exposes what the browser tests and the benchmark read back.
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { TransformControls } from 'three/addons/controls/TransformControls.js';

const $ = (id) => document.getElementById(id);
// A handle farther than this from its target (share of the diagonal) is said to lag: the
// threshold `motif deform` warns at.
const HANDLE_LAG = 0.01;

const state = {
  connected: false, upAxis: 'y', name: null, vertices: 0, triangles: 0, isMesh: false, bbox: null, diagonal: 0,
  meshVersion: 0, handles: 0, handleSamples: [], symmetryResidual: null, restResidual: null,
  maxDisplacement: 0, lastFrameMs: null, medianFrameMs: null, lastSolveMs: null, framesReceived: 0,
  frameTimes: [], frameLog: [], annotation: null, offsets: null, cells: null, totalCells: null, retargetVersion: 0, resizedSteps: null,
  retargetVertices: 0, detections: null, busy: null, progress: null, saved: [], errors: [], released: 0,
  undo: 0, redo: 0, downloads: [], renderer: null, handleTransforms: [], progressLog: [], files: null,
};
window.motif = { state };

// ---------------------------------------------------------------------------------------------
// Scene
const viewport = $('viewport');
// A software WebGL (SwiftShader, llvmpipe: a machine without a usable GPU) rasterises every
// multisample on the CPU: 4x MSAA made a 200k-triangle frame ~3x slower there. Antialias only on
// a hardware renderer.
function rendererName() {
  const gl = document.createElement('canvas').getContext('webgl2');
  if (!gl) return '';
  const dbg = gl.getExtension('WEBGL_debug_renderer_info');
  const name = dbg ? gl.getParameter(dbg.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER);
  const lose = gl.getExtension('WEBGL_lose_context');
  if (lose) lose.loseContext();
  return String(name);
}
const gpuName = rendererName();
const software = /swiftshader|llvmpipe|softpipe|software/i.test(gpuName);
const renderer = new THREE.WebGLRenderer({ antialias: !software });
renderer.setPixelRatio(1);
state.renderer = { name: gpuName, software, antialias: !software };
viewport.appendChild(renderer.domElement);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0xeef0f4);
const camera = new THREE.PerspectiveCamera(40, 1, 0.01, 1000);
scene.add(new THREE.HemisphereLight(0xffffff, 0x8890a0, 1.6));
const sun = new THREE.DirectionalLight(0xffffff, 1.6);
camera.add(sun);
sun.position.set(1, 2, 3);
scene.add(camera);
let orbit = new OrbitControls(camera, renderer.domElement);
const gizmo = new TransformControls(camera, renderer.domElement);
const gizmoTarget = new THREE.Object3D();
scene.add(gizmoTarget);
scene.add(gizmo.getHelper());

// Lambert shading costs ~20% less per frame than the physically based material on a software
// renderer (measured on the 215k-triangle windmill); a GPU draws either in about a millisecond.
const material = software
  ? new THREE.MeshLambertMaterial({ color: 0xb9c3d6, flatShading: true, side: THREE.DoubleSide })
  : new THREE.MeshStandardMaterial({ color: 0xb9c3d6, roughness: 0.7, metalness: 0.05, flatShading: true, side: THREE.DoubleSide });
const pointMaterial = new THREE.PointsMaterial({ size: 3, sizeAttenuation: false, color: 0x6d7890 });
// `geometry` holds the model on the CPU (picking, bounds, overlays). A mesh is drawn from
// `drawGeometry`, whose positions (and normals) live in WebGL buffers this page owns: a drag
// frame is one bufferSubData of the new positions, no geometry rebuild, no CPU normals.
let geometry = null, object = null, restPositions = null;
let drawGeometry = null, gpuPositions = null, gpuNormals = null, pickMesh = null;
const gl = renderer.getContext();
const syncPixel = new Uint8Array(4);
// Waits until the GPU has executed everything issued so far (finish() does not wait in Chrome;
// reading a pixel does), so the frame-time readout measures drawn frames, not queued commands.
function gpuSync() { gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, syncPixel); }
let retargetObject = null;
// The radius of the sphere the camera was last framed on.
let framedRadius = 0;
const overlays = { bbox: new THREE.Group(), symmetry: new THREE.Group(), detections: new THREE.Group(), handles: new THREE.Group(), offsets: new THREE.Group() };
Object.values(overlays).forEach((g) => scene.add(g));

let renderQueued = false;
function requestRender() {
  // While a handle is dragged, deformation frames draw everything (gizmo included) when they land:
  // a render per mouse move as well would double the GPU work (and its queue delays the frames).
  if (inFlight || (gizmo.dragging && handles.length)) return;
  if (renderQueued) return;
  renderQueued = true;
  requestAnimationFrame(() => { renderQueued = false; renderer.render(scene, camera); });
}
function resize() {
  const w = viewport.clientWidth, h = viewport.clientHeight;
  renderer.setSize(w, h);
  camera.aspect = w / Math.max(h, 1);
  camera.updateProjectionMatrix();
  requestRender();
}
window.addEventListener('resize', resize);
orbit.addEventListener('change', requestRender);
// Which axis points up on screen. CAD files (STL from OpenSCAD, FreeCAD, slicers) are Z-up, as
// Blender is; OBJ, glTF and the generated examples are Y-up. An STL opens Z-up, anything else
// Y-up, and the View panel's "Z up" box switches.
function setUp(zUp) {
  state.upAxis = zUp ? 'z' : 'y';
  $('z-up').checked = zUp;
  camera.up.set(0, zUp ? 0 : 1, zUp ? 1 : 0);
  // The orbit keeps the up axis it was made with.
  const enabled = orbit.enabled;
  orbit.dispose();
  orbit = new OrbitControls(camera, renderer.domElement);
  orbit.enabled = enabled;
  orbit.addEventListener('change', requestRender);
  if (geometry) { frameCamera(); drawBox(); }
  requestRender();
}
gizmo.addEventListener('change', requestRender);
gizmo.addEventListener('dragging-changed', (e) => {
  orbit.enabled = !e.value;
  if (!e.value) { endDrag(); requestRender(); }
});
gizmo.addEventListener('objectChange', onGizmoMove);

// ---------------------------------------------------------------------------------------------
// Connection
let ws = null;
let pendingBinary = [];
function connect() {
  ws = new WebSocket(`ws://${location.host}/ws`);
  ws.binaryType = 'arraybuffer';
  ws.onopen = () => {
    state.connected = true;
    const params = new URLSearchParams(location.search);
    if (params.get('example')) send({ type: 'example', name: params.get('example') });
    if (params.get('open')) send({ type: 'open', path: params.get('open') });
  };
  ws.onclose = () => { state.connected = false; message('connection closed; reload the page', true); };
  ws.onmessage = (ev) => (typeof ev.data === 'string' ? onText(JSON.parse(ev.data)) : onBinary(ev.data, performance.now()));
}
function send(m) {
  if (ws && ws.readyState === WebSocket.OPEN) ws.send(JSON.stringify(m));
}
// `n` with its noun in the right number: count(1, 'handle') is "1 handle".
const count = (n, one, many = `${one}s`) => `${n} ${n === 1 ? one : many}`;
function message(text, isError = false) {
  if (isError) state.errors.push(text);
  const box = $('messages');
  // The same message again counts up on the newest line instead of stacking copies.
  const top = box.firstChild;
  if (top && top.dataset.text === text) {
    top.dataset.count = String(Number(top.dataset.count || 1) + 1);
    top.textContent = `${text} (×${top.dataset.count})`;
  } else {
    const div = document.createElement('div');
    div.textContent = text;
    div.dataset.text = text;
    if (isError) div.className = 'error';
    box.prepend(div);
    while (box.children.length > 6) box.lastChild.remove();
  }
  box.scrollTop = 0;
}
// Errors that a newly opened model makes moot ("open a model first") leave the list.
function clearErrors() { for (const d of [...$('messages').querySelectorAll('.error')]) d.remove(); }
// Shows a result or warning that may sit below the fold of a short window (1280 × 800 hid the
// resize warning under the progress panel).
function reveal(el) { if (el && !el.hidden && el.scrollIntoView) el.scrollIntoView({ block: 'nearest' }); }
// What the progress line calls each job (the protocol's names are for programs).
const JOB_NAMES = {
  detect: 'detecting building blocks', detect_symmetry: 'detecting symmetry', example: 'generating the example',
  export: 'exporting', load_annotation: 'loading the annotation', load_detections: 'loading detections',
  offsets: 'finding offsets', open: 'opening', save_annotation: 'saving the annotation', save_detections: 'saving the detections',
  set_handles: 'preparing the handles', upload: 'uploading', retarget: 'resizing',
};
const jobName = (job) => JOB_NAMES[job] || job.replace(/_/g, ' ');
function setBusy(job) {
  state.busy = job;
  $('cancel').disabled = !job;
  // One job at a time: the other buttons wait for it (a second request used to queue silently
  // and then drop the first one's result).
  for (const b of document.querySelectorAll('#side button')) if (b.id !== 'cancel') b.disabled = !!job || (MESH_ONLY.has(b.id) && !state.isMesh);
  $('progress').textContent = job ? `${jobName(job)}…` : '';
}
// Deforming and resizing need a triangle mesh: their buttons wait for one (a point cloud, or no
// model yet, leaves them off rather than failing when clicked).
// Export stays on: a point cloud can be written in another format.
const MESH_ONLY = new Set(['undo', 'redo', 'reset', 'delete-handle', 'find-offsets', 'export-resized']);

function onText(m) {
  // A request that succeeds makes the errors before it moot ("open a model first", "nothing
  // resized yet"): they leave the list (state.errors keeps them).
  if (['model', 'annotation', 'saved', 'offsets', 'retargeted', 'detections'].includes(m.type)) clearErrors();
  switch (m.type) {
    case 'hello':
      $('example-select').replaceChildren(...m.examples.map((n) => new Option(n, n)));
      $('example-select').value = 'windmill';
      send({ type: 'list_files' });
      break;
    // The files under the root, offered as completions of the path fields.
    case 'files':
      state.files = { models: m.models, json: m.json, truncated: m.truncated };
      $('model-files').replaceChildren(...m.models.map((f) => new Option(f)));
      $('json-files').replaceChildren(...m.json.map((f) => new Option(f)));
      break;
    case 'model': onModel(m); break;
    case 'progress':
      state.progress = m;
      state.progressLog.push(m);
      if (state.progressLog.length > 200) state.progressLog.shift();
      $('progress').textContent = `${jobName(m.job)}: ${m.stage}` + (m.total ? ` ${m.done}/${m.total}` : m.done ? ` ${m.done}` : '');
      break;
    case 'cancelled':
      setBusy(null);
      message(`${jobName(m.job)}: cancelled`);
      if (m.job === 'set_handles') handlesFailed();
      break;
    case 'annotation': setBusy(null); onAnnotation(m); break;
    case 'saved':
      setBusy(null); state.saved.push(...m.paths); message(`wrote ${m.paths.join(', ')}`);
      for (const n of m.notes || []) message(n, true);
      send({ type: 'list_files' });
      break;
    case 'handles': onHandles(m); break;
    case 'deformed': onDeformed(m); break;
    case 'offsets': setBusy(null); onOffsets(m); break;
    case 'retargeted': pendingBinary.push(m); break;
    case 'detections': setBusy(null); onDetections(m); break;
    case 'error':
      if (m.request === 'drag') { inFlight = false; requestRender(); }
      if (m.request !== 'drag' && m.request !== 'release' && m.request !== 'retarget') setBusy(null);
      message(m.message, true);
      // The tick box the message asks for may be below the fold.
      if (/already exists/.test(m.message)) reveal($('files'));
      if (m.request === 'set_handles') handlesFailed();
      if (m.request === 'retarget') { restoreSteps(); committing = null; }
      break;
  }
}

// Binary messages: a 48-byte header (protocol.rs), then positions [, normals] [, triangles].
const HEADER = 48;
function onBinary(buf, tRecv) {
  const h = new DataView(buf, 0, HEADER);
  const head = {
    kind: h.getUint32(0, true), seq: h.getUint32(4, true), nv: h.getUint32(8, true), nt: h.getUint32(12, true),
    solveMs: h.getFloat32(16, true), queueMs: h.getFloat32(20, true), encodeMs: h.getFloat32(24, true),
    flags: h.getUint32(28, true), receivedAt: h.getFloat64(32, true), sentAt: h.getFloat64(40, true),
  };
  const { kind, nv, nt } = head;
  if (kind === 4) { onFile(new TextDecoder().decode(new Uint8Array(buf, HEADER, nv)), new Uint8Array(buf, HEADER + nv, nt)); return; }
  const pos = new Float32Array(buf, HEADER, nv * 3);
  const after = HEADER + nv * 12 * ((head.flags & 1) ? 2 : 1);
  if (kind === 1) setModelGeometry(pos, nt ? new Uint32Array(buf, after, nt * 3) : null);
  else if (kind === 2) onFrame(head, pos, (head.flags & 1) ? new Float32Array(buf, HEADER + nv * 12, nv * 3) : null, tRecv);
  else if (kind === 3) onRetargetedMesh(pos, new Uint32Array(buf, after, nt * 3), pendingBinary.shift());
}

// An exported file: saved by the browser (Blob + a download link).
function onFile(name, bytes) {
  const url = URL.createObjectURL(new Blob([bytes], { type: 'application/octet-stream' }));
  const a = document.createElement('a');
  a.href = url; a.download = name; a.style.display = 'none';
  document.body.append(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(url), 10000);
  state.downloads.push(name);
}

// ---------------------------------------------------------------------------------------------
// View
function onModel(m) {
  Object.assign(state, { name: m.name, vertices: m.vertices, triangles: m.triangles, isMesh: m.triangles > 0, bbox: m.bbox, diagonal: m.diagonal,
    symmetryResidual: null, restResidual: null, handles: 0, offsets: null, cells: null, totalCells: null, detections: null, maxDisplacement: 0, symmetryCentre: null, annotation: null });
  // Frame times are per model: a median carried over from a small model says nothing of a large one.
  state.frameTimes = []; state.medianFrameMs = null; state.lastFrameMs = null;
  setBusy(null);
  $('start-hint').hidden = true;
  if ((/\.stl$/i.test(m.name)) !== (state.upAxis === 'z')) setUp(/\.stl$/i.test(m.name));
  const [lo, hi] = m.bbox;
  const size = hi.map((v, k) => v - lo[k]);
  $('model-info').textContent = `${m.name}\n${m.vertices} ${m.triangles ? 'vertices' : 'points'}, ${m.triangles} triangles\n` +
    `size ${size.map((v) => v.toPrecision(3)).join(' × ')} (diagonal ${m.diagonal.toPrecision(3)})` +
    (m.warnings.length ? `\n${m.warnings.join('\n')}` : '');
  if (!state.isMesh) $('model-info').textContent += '\na point cloud: Deform and Resize need a triangle mesh';
  // Export names follow the model (they kept the previous model's).
  $('export-path').value = `${stem()}-edited.${$('export-format').value}`;
  $('export-resized-path').value = `${stem()}-resized.obj`;
  handles = []; undoStack = []; redoStack = []; updateUndo(); historyBase = { handles: [], steps: null };
  inFlight = wantFrame = handlesPending = undoOnHandles = releaseWanted = false; sentAt.clear();
  clearGroup(overlays.detections); clearGroup(overlays.offsets); clearGroup(overlays.symmetry); clearGroup(overlays.handles);
  $('steps').replaceChildren(); $('resize-info').textContent = ''; $('resize-warning').hidden = true; $('detections-info').textContent = ''; $('deform-info').textContent = '';
  $('symmetry-info').textContent = '';
  if (retargetObject) { scene.remove(retargetObject); retargetObject.geometry.dispose(); retargetObject = null; }
  state.resizedSteps = null; committing = null; ignoreBelow = retargetSeq + 1;
  overlays.handles.visible = true; // hidden while a resized model covered the original
  gizmo.detach();
  if (m.annotation) onAnnotation({ annotation: m.annotation, groups: [], max_residual: null, ok: true, ms: 0 });
}

function setModelGeometry(pos, index) {
  if (object) { scene.remove(object); geometry.dispose(); }
  if (drawGeometry) { drawGeometry.dispose(); gl.deleteBuffer(gpuPositions); gl.deleteBuffer(gpuNormals); drawGeometry = gpuPositions = gpuNormals = null; }
  geometry = new THREE.BufferGeometry();
  geometry.setAttribute('position', new THREE.BufferAttribute(new Float32Array(pos), 3));
  restPositions = new Float32Array(pos);
  geometry.computeBoundingBox();
  geometry.computeBoundingSphere();
  if (index) {
    geometry.setIndex(new THREE.BufferAttribute(new Uint32Array(index), 1));
    geometry.computeVertexNormals();
    const nv = pos.length / 3;
    gpuPositions = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, gpuPositions);
    gl.bufferData(gl.ARRAY_BUFFER, restPositions, gl.DYNAMIC_DRAW);
    gpuNormals = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, gpuNormals);
    gl.bufferData(gl.ARRAY_BUFFER, geometry.getAttribute('normal').array, gl.DYNAMIC_DRAW);
    drawGeometry = new THREE.BufferGeometry();
    drawGeometry.setAttribute('position', new THREE.GLBufferAttribute(gpuPositions, gl.FLOAT, 3, 4, nv));
    drawGeometry.setAttribute('normal', new THREE.GLBufferAttribute(gpuNormals, gl.FLOAT, 3, 4, nv));
    drawGeometry.setIndex(geometry.index);
    drawGeometry.boundingSphere = geometry.boundingSphere.clone();
    pickMesh = new THREE.Mesh(geometry, material);
    object = new THREE.Mesh(drawGeometry, material);
    object.frustumCulled = false; // the bounds change while dragging; the model is always in view
  } else {
    object = new THREE.Points(geometry, pointMaterial);
  }
  scene.add(object);
  frameCamera();
  drawBox();
  state.meshVersion++;
  requestRender();
}

function frameCamera(sphere) {
  const s = sphere || geometry.boundingSphere;
  framedRadius = s.radius;
  orbit.target.copy(s.center);
  camera.near = s.radius / 100; camera.far = s.radius * 100;
  // From the front, a little above and to the right, whichever axis is up.
  const from = state.upAxis === 'z' ? new THREE.Vector3(0.55, -1, 0.35) : new THREE.Vector3(0.55, 0.35, 1);
  camera.position.copy(s.center).add(from.normalize().multiplyScalar(s.radius * 3.3));
  camera.updateProjectionMatrix();
  orbit.update();
}

function niceStep(x) {
  const p = Math.pow(10, Math.floor(Math.log10(x)));
  return [1, 2, 5, 10].map((k) => k * p).find((v) => v >= x) || p;
}

function drawBox() {
  clearGroup(overlays.bbox);
  const box = geometry.boundingBox;
  overlays.bbox.add(new THREE.Box3Helper(box, 0x8a94aa));
  const size = box.getSize(new THREE.Vector3());
  // The floor grid under the model: the XZ plane at its lowest y, or the XY plane at its lowest z.
  const zUp = state.upAxis === 'z';
  const across = zUp ? size.y : size.z;
  const cell = niceStep(Math.max(size.x, across) / 8);
  const n = Math.ceil(Math.max(size.x, across) / cell) + 2;
  const grid = new THREE.GridHelper(n * cell, n, 0xb0b7c6, 0xd3d7df);
  if (zUp) {
    grid.rotation.x = Math.PI / 2;
    grid.position.set((box.min.x + box.max.x) / 2, (box.min.y + box.max.y) / 2, box.min.z);
  } else {
    grid.position.set((box.min.x + box.max.x) / 2, box.min.y, (box.min.z + box.max.z) / 2);
  }
  overlays.bbox.add(grid);
  state.gridCell = cell;
  $('hud').dataset.scale = `grid ${cell}`;
  updateHud();
  overlays.bbox.visible = $('show-bbox').checked;
}

function clearGroup(g) {
  for (const c of [...g.children]) {
    g.remove(c);
    c.traverse((o) => { if (o.geometry) o.geometry.dispose(); });
  }
}

// Flat shading takes face normals from screen-space derivatives in the shader; smooth shading
// uses vertex normals, sent by the server with every drag frame while it is on.
function uploadCpuNormals() {
  if (!geometry || !geometry.index || !gpuNormals) return;
  geometry.computeVertexNormals();
  gl.bindBuffer(gl.ARRAY_BUFFER, gpuNormals);
  gl.bufferSubData(gl.ARRAY_BUFFER, 0, geometry.getAttribute('normal').array);
}
$('shade-flat').onchange = $('shade-smooth').onchange = () => {
  material.flatShading = $('shade-flat').checked;
  material.needsUpdate = true;
  if (!material.flatShading) uploadCpuNormals();
  requestRender();
};
$('wireframe').onchange = () => { material.wireframe = $('wireframe').checked; requestRender(); };
$('z-up').onchange = () => setUp($('z-up').checked);
$('show-bbox').onchange = () => { overlays.bbox.visible = $('show-bbox').checked; requestRender(); };
$('example-open').onclick = () => { setBusy('example'); send({ type: 'example', name: $('example-select').value }); };
$('open-btn').onclick = () => { setBusy('open'); send({ type: 'open', path: $('open-path').value }); };
$('upload').onchange = async () => {
  const f = $('upload').files[0];
  if (!f) return;
  const name = new TextEncoder().encode(f.name);
  const bytes = new Uint8Array(await f.arrayBuffer());
  const msg = new Uint8Array(4 + name.length + bytes.length);
  new DataView(msg.buffer).setUint32(0, name.length, true);
  msg.set(name, 4); msg.set(bytes, 4 + name.length);
  setBusy('upload');
  ws.send(msg);
  $('upload').value = '';
};
$('cancel').onclick = () => send({ type: 'cancel' });

// ---------------------------------------------------------------------------------------------
// Structure: symmetry elements drawn from the annotation's matrices.
function classify(m) {
  // m: row-major 4x4. Linear part R, translation t.
  const R = new THREE.Matrix3().set(m[0][0], m[0][1], m[0][2], m[1][0], m[1][1], m[1][2], m[2][0], m[2][1], m[2][2]);
  const t = new THREE.Vector3(m[0][3], m[1][3], m[2][3]);
  const det = R.determinant();
  const e = R.elements; // column-major
  const r = (i, j) => e[j * 3 + i];
  const trace = r(0, 0) + r(1, 1) + r(2, 2);
  if (det < 0 && Math.abs(trace - 1) < 1e-3) {
    // Reflection R = I - 2 n nᵀ: n from the largest column of I - R; the plane holds t / 2.
    let best = null;
    for (let j = 0; j < 3; j++) {
      const c = new THREE.Vector3((j === 0) - r(0, j), (j === 1) - r(1, j), (j === 2) - r(2, j));
      if (!best || c.lengthSq() > best.lengthSq()) best = c;
    }
    return { kind: 'mirror', normal: best.normalize(), point: t.clone().multiplyScalar(0.5) };
  }
  if (det > 0 && trace < 3 - 1e-6) {
    const axis = new THREE.Vector3(r(2, 1) - r(1, 2), r(0, 2) - r(2, 0), r(1, 0) - r(0, 1));
    const angle = Math.acos(Math.min(1, Math.max(-1, (trace - 1) / 2)));
    if (axis.lengthSq() < 1e-12) {
      // 180°: axis from the largest column of R + I.
      let best = null;
      for (let j = 0; j < 3; j++) {
        const c = new THREE.Vector3(r(0, j) + (j === 0), r(1, j) + (j === 1), r(2, j) + (j === 2));
        if (!best || c.lengthSq() > best.lengthSq()) best = c;
      }
      axis.copy(best);
    }
    axis.normalize();
    // A point of the axis: (I - R + a aᵀ) p = t.
    const A = new THREE.Matrix3().set(
      1 - r(0, 0) + axis.x * axis.x, -r(0, 1) + axis.x * axis.y, -r(0, 2) + axis.x * axis.z,
      -r(1, 0) + axis.y * axis.x, 1 - r(1, 1) + axis.y * axis.y, -r(1, 2) + axis.y * axis.z,
      -r(2, 0) + axis.z * axis.x, -r(2, 1) + axis.z * axis.y, 1 - r(2, 2) + axis.z * axis.z);
    const p = t.clone().applyMatrix3(A.invert());
    return { kind: 'rotation', axis, point: p, order: Math.round((2 * Math.PI) / angle) };
  }
  return { kind: 'other' };
}

function onAnnotation(m) {
  clearGroup(overlays.symmetry);
  const a = m.annotation;
  // The centre of the model the annotation belongs to: its box arrives with it (the geometry
  // may still be the previous model's, whose centre misplaced the planes and axes).
  const center = state.bbox
    ? new THREE.Vector3(...state.bbox[0]).add(new THREE.Vector3(...state.bbox[1])).multiplyScalar(0.5)
    : new THREE.Vector3();
  state.symmetryCentre = center.toArray();
  const size = state.diagonal || 1;
  let mirrors = 0, axes = 0, instanceSets = 0;
  for (const s of a.symmetries) {
    if (!s.generators) { instanceSets++; continue; }
    for (const g of s.generators) {
      const el = classify(g);
      if (el.kind === 'mirror') {
        mirrors++;
        const plane = new THREE.Mesh(new THREE.PlaneGeometry(size * 0.8, size * 0.8),
          new THREE.MeshBasicMaterial({ color: 0x3b82f6, transparent: true, opacity: 0.09, side: THREE.DoubleSide, depthWrite: false }));
        plane.add(new THREE.LineSegments(new THREE.EdgesGeometry(plane.geometry), new THREE.LineBasicMaterial({ color: 0x3b82f6 })));
        const onPlane = center.clone().sub(el.normal.clone().multiplyScalar(center.clone().sub(el.point).dot(el.normal)));
        plane.position.copy(onPlane);
        plane.quaternion.setFromUnitVectors(new THREE.Vector3(0, 0, 1), el.normal);
        overlays.symmetry.add(plane);
      } else if (el.kind === 'rotation') {
        axes++;
        const foot = el.point.clone().add(el.axis.clone().multiplyScalar(center.clone().sub(el.point).dot(el.axis)));
        const half = el.axis.clone().multiplyScalar(size * 0.45);
        const line = new THREE.Line(new THREE.BufferGeometry().setFromPoints([foot.clone().sub(half), foot.clone().add(half)]),
          new THREE.LineBasicMaterial({ color: 0xe4572e }));
        overlays.symmetry.add(line);
      }
    }
  }
  state.annotation = { symmetries: a.symmetries.length, mirrors, axes, instanceSets, ok: m.ok, maxResidual: m.max_residual };
  const groups = m.groups.map((g) => `${g.schoenflies} (order ${g.order}), residual ${g.max_residual.toExponential(1)}`).join('\n');
  const n = a.symmetries.length;
  $('symmetry-info').textContent = (n ? `${n} ${n === 1 ? 'symmetry' : 'symmetries'}: ${count(mirrors, 'mirror plane')}, ${count(axes, 'rotation axis', 'rotation axes')}` : 'no symmetry found') +
    (instanceSets ? `, ${count(instanceSets, 'instance set')}` : '') + (groups ? `\n${groups}` : '') +
    (m.max_residual != null && n ? `\nannotation residual ${m.max_residual.toExponential(2)} of the diagonal${m.ok ? '' : ' (does not fit!)'}` : '');
  overlays.symmetry.visible = $('show-symmetry').checked;
  // A new annotation means a new deformation session on the server, from the rest shape: the
  // page shows that shape too (it kept showing the deformed one, which an export no longer
  // wrote), and the old handles leave the undo history with it.
  handles = []; clearGroup(overlays.handles); gizmo.detach(); state.handles = 0;
  inFlight = wantFrame = handlesPending = undoOnHandles = false; sentAt.clear();
  undoStack = []; redoStack = []; updateUndo();
  historyBase = { handles: [], steps: retargetObject ? shownSteps.slice() : null };
  if (isDeformed()) { showRest(); $('deform-info').textContent = 'no handles (a new annotation starts from the undeformed model)'; }
  requestRender();
}
// Detecting or loading an annotation discards the deformation: only after the user agrees.
function keepsDeformation(what) {
  if (!isDeformed() && !handles.length) return true;
  return window.confirm(`${what} starts a new deformation from the undeformed model: the current one (${count(handles.length, 'handle')}) will be discarded. Export it first to keep it.\n\nDiscard it and continue?`);
}
$('show-symmetry').onchange = () => { overlays.symmetry.visible = $('show-symmetry').checked; requestRender(); };
$('detect-symmetry').onclick = () => {
  if (!keepsDeformation('Detecting symmetry')) return;
  setBusy('detect_symmetry'); send({ type: 'detect_symmetry' });
};
$('load-annotation').onclick = () => {
  if (!keepsDeformation('Loading an annotation')) return;
  setBusy('load_annotation'); send({ type: 'load_annotation', path: $('annotation-path').value });
};
const stem = () => (state.name || 'model').replace(/^.*\//, '').replace(/\.[^.]*$/, '');
$('save-annotation').onclick = () => {
  // An empty field names the file after the model (STEM.sym.json), as saving detections does.
  if (!$('annotation-path').value.trim()) $('annotation-path').value = `${stem()}.sym.json`;
  setBusy('save_annotation'); send({ type: 'save_annotation', path: $('annotation-path').value, overwrite: $('overwrite').checked });
};

const palette = [0xe6194b, 0x3cb44b, 0x4363d8, 0xf58231, 0x911eb4, 0x42d4f4, 0xf032e6, 0x9a6324, 0x469990, 0x800000];
function onDetections(m) {
  clearGroup(overlays.detections);
  const colors = new Float32Array(m.point_class.length * 3);
  const c = new THREE.Color();
  m.point_class.forEach((k, i) => {
    c.set(k < 0 ? 0x9aa3b5 : palette[k % palette.length]);
    colors.set([c.r, c.g, c.b], i * 3);
  });
  const g = new THREE.BufferGeometry();
  g.setAttribute('position', geometry.getAttribute('position'));
  g.setAttribute('color', new THREE.BufferAttribute(colors, 3));
  overlays.detections.add(new THREE.Points(g, new THREE.PointsMaterial({ size: 3, sizeAttenuation: false, vertexColors: true })));
  let instances = 0;
  m.classes.forEach((cl, k) => {
    for (const [lo, hi] of cl.boxes) {
      instances++;
      overlays.detections.add(new THREE.Box3Helper(new THREE.Box3(new THREE.Vector3(...lo), new THREE.Vector3(...hi)), palette[k % palette.length]));
    }
  });
  // A result names the scan it was found on; shown on another model its boxes float anywhere.
  const base = (p) => String(p || '').replace(/^.*[\\/]/, '');
  const otherScene = !!m.scene && base(m.scene) !== base(state.name);
  state.detections = { scene: m.scene, classes: m.classes.length, instances, coloured: m.point_class.filter((k) => k >= 0).length, otherScene };
  const info = $('detections-info');
  info.replaceChildren(document.createTextNode(`${m.scene}: ${m.classes.length} classes, ${instances} instances`));
  if (otherScene) {
    const warn = `these detections were made on ${base(m.scene)}, not on ${base(state.name)}: their boxes need not line up with this model`;
    const w = document.createElement('div'); w.className = 'warn'; w.style.color = '#b3261e'; w.textContent = warn;
    info.append(w);
    message(warn, true);
  }
  info.classList.add('legend');
  m.classes.forEach((cl, k) => {
    const d = document.createElement('div');
    const sw = document.createElement('span');
    sw.style.background = '#' + palette[k % palette.length].toString(16).padStart(6, '0');
    d.append(sw, `${cl.name}: ${cl.boxes.length} instances, ${cl.points} points`);
    info.append(d);
  });
  overlays.detections.visible = $('show-detections').checked;
  requestRender();
}
$('show-detections').onchange = () => { overlays.detections.visible = $('show-detections').checked && !isDeformed(); requestRender(); };
$('load-detections').onclick = () => { setBusy('load_detections'); send({ type: 'load_detections', path: $('detections-path').value }); };
$('detect').onclick = () => {
  // The field may name the file the shown detections came from (a ground truth): Save after
  // Detect must not offer to replace it, so it empties and Save names a new file.
  $('detections-path').value = '';
  setBusy('detect'); send({ type: 'detect' });
};
$('save-detections').onclick = () => {
  // An empty field names the file after the model (STEM.detect.json), as an export does.
  if (!$('detections-path').value.trim()) $('detections-path').value = `${stem()}.detect.json`;
  setBusy('save_detections');
  send({ type: 'save_detections', path: $('detections-path').value, overwrite: $('overwrite').checked });
};

// ---------------------------------------------------------------------------------------------
// Deform: handles are unions of balls on the rest shape; each has a rest→target transform.
let handles = []; // { balls: [{center:[x,y,z], radius}], matrix: THREE.Matrix4 }
let active = -1;
let undoStack = [], redoStack = [];
let seq = 0, inFlight = false, wantFrame = false;
const sentAt = new Map();

$('radius-value').textContent = $('handle-radius').value;
$('handle-radius').oninput = () => { $('radius-value').textContent = $('handle-radius').value; };
$('gizmo-translate').onchange = $('gizmo-rotate').onchange = () => gizmo.setMode($('gizmo-rotate').checked ? 'rotate' : 'translate');

function restCentroid(h) {
  const c = new THREE.Vector3();
  h.balls.forEach((b) => c.add(new THREE.Vector3(...b.center)));
  return c.multiplyScalar(1 / h.balls.length);
}
// One step of the undo history: the handles and, when a resized model is shown, its steps
// (null: none shown). The top of the stack is what is on screen; below the bottom lies
// `historyBase`.
function handlesSnapshot() {
  return handles.map((h) => ({ balls: h.balls.map((b) => ({ center: [...b.center], radius: b.radius })), matrix: h.matrix.clone() }));
}
function snapshot() { return { handles: handlesSnapshot(), steps: retargetObject ? shownSteps.slice() : null }; }
// What lies below the bottom of the stack: no handles, and the size shown when the history
// began (a new annotation clears the history but keeps a resized model on screen).
let historyBase = { handles: [], steps: null };
const historyTop = () => (undoStack.length ? undoStack[undoStack.length - 1] : historyBase);
const handlesKey = (hs) => JSON.stringify(hs.map((h) => [h.balls, h.matrix.elements]));
function pushUndo() { undoStack.push(snapshot()); redoStack = []; updateUndo(); }
function updateUndo() { state.undo = undoStack.length; state.redo = redoStack.length; }
function transformsArray() {
  return handles.map((h) => { const e = h.matrix.clone().transpose().elements; return [e.slice(0, 4), e.slice(4, 8), e.slice(8, 12), e.slice(12, 16)]; });
}
function drawHandles() {
  clearGroup(overlays.handles);
  handles.forEach((h, i) => {
    for (const b of h.balls) {
      const s = new THREE.Mesh(new THREE.SphereGeometry(b.radius, 16, 12),
        new THREE.MeshBasicMaterial({ color: i === active ? 0xf59e0b : 0x10b981, wireframe: true, transparent: true, opacity: 0.6 }));
      s.position.set(...b.center).applyMatrix4(h.matrix);
      s.userData.handle = i;
      overlays.handles.add(s);
    }
  });
  requestRender();
}
function placeGizmo() {
  // (A stale index, left by the model before, selects nothing.)
  if (active < 0 || !handles[active]) { gizmo.detach(); return; }
  const h = handles[active];
  const g = h.matrix.clone().multiply(new THREE.Matrix4().makeTranslation(restCentroid(h)));
  g.decompose(gizmoTarget.position, gizmoTarget.quaternion, gizmoTarget.scale);
  gizmoTarget.updateMatrixWorld();
  gizmo.attach(gizmoTarget);
}
// Sends the handle set. A handle with `fresh` set (new, or a ball added) gets its target from
// the server (fitted to the current shape); the others keep the target given here. The server
// replies with every target and a frame, so earlier drags are kept, never snapped back.
let handlesPending = false, undoOnHandles = false;
function sendHandles() {
  state.symmetryResidual = null;
  if (!handles.length) {
    handlesPending = false;
    send({ type: 'set_handles', handles: [] });
    showRest();
    return;
  }
  handlesPending = true;
  setBusy('set_handles');
  send({ type: 'set_handles', handles: handles.map((h) => ({ balls: h.balls })), transforms: handles.map((h, i) => (h.fresh ? null : transformsArray()[i])) });
}
const fromRows = (rows) => new THREE.Matrix4().set(...rows.flat());
function onHandles(m) {
  setBusy(null);
  handlesPending = false;
  state.handles = m.handles;
  state.handleSamples = m.samples;
  m.transforms.forEach((t, i) => { if (handles[i]) { handles[i].matrix = fromRows(t); handles[i].fresh = false; } });
  state.handleTransforms = m.transforms;
  $('deform-info').textContent = `${count(m.handles, 'handle')}, samples ${m.samples.join(' / ')} of ${m.total_samples}, ${m.dof} DoF\n` +
    `precompute ${m.session_ms.toFixed(0)} ms, factorisation ${m.prefactor_ms.toFixed(1)} ms`;
  if (undoOnHandles) { undoOnHandles = false; pushUndo(); }
  placeGizmo();
  drawHandles();
  if (wantFrame) requestFrame();
}
// The server refused (or the user cancelled) a handle set: back to the last confirmed one.
function handlesFailed() {
  handlesPending = false;
  undoOnHandles = false;
  const last = historyTop().handles;
  const same = JSON.stringify(last.map((h) => h.balls)) === JSON.stringify(handles.map((h) => h.balls));
  if (same && !handles.some((h) => h.fresh)) return;
  handles = last.map((h) => ({ balls: h.balls.map((b) => ({ ...b })), matrix: h.matrix.clone() }));
  active = handles.length - 1;
  state.handles = handles.length;
  placeGizmo(); drawHandles();
  if (handles.length) sendHandles(); else showRest();
}
function showRest() {
  if (!geometry || !restPositions) return;
  geometry.getAttribute('position').array.set(restPositions);
  if (geometry.index) {
    gl.bindBuffer(gl.ARRAY_BUFFER, gpuPositions);
    gl.bufferSubData(gl.ARRAY_BUFFER, 0, restPositions);
    if (!material.flatShading) uploadCpuNormals();
  }
  state.meshVersion++;
  state.maxDisplacement = 0;
  followDeformation();
  requestRender();
}

function pick(ev) {
  if (!object || !state.isMesh) return;
  if (retargetObject && !object.visible) {
    message('the resized model is not deformed here: export it and open the export to deform it (or tick "original" to place handles on the original)');
    return;
  }
  // While a job other than preparing the handles runs, the shape on screen may be about to be
  // replaced (a model opening, a resize): a handle placed now would belong to the old one.
  if (state.busy && state.busy !== 'set_handles') { message(`handles wait until ${jobName(state.busy)} is done`); return; }
  const rect = renderer.domElement.getBoundingClientRect();
  const ndc = new THREE.Vector2(((ev.clientX - rect.left) / rect.width) * 2 - 1, -((ev.clientY - rect.top) / rect.height) * 2 + 1);
  const ray = new THREE.Raycaster();
  ray.setFromCamera(ndc, camera);
  // A click on a handle's ball selects that handle (the gizmo moves to it; Delete removes it).
  const onBall = ray.intersectObjects(overlays.handles.children, false)[0];
  if (onBall && !ev.shiftKey) { selectHandle(onBall.object.userData.handle); return; }
  // Picked on the CPU copy of the current shape (bounds refreshed: drags move them).
  geometry.computeBoundingSphere();
  const hit = ray.intersectObject(pickMesh, false)[0];
  if (!hit) return;
  // Back to the rest shape through barycentric coordinates of the hit triangle.
  const pos = geometry.getAttribute('position');
  const [a, b, c] = [hit.face.a, hit.face.b, hit.face.c];
  const P = (arr, i) => new THREE.Vector3(arr[3 * i], arr[3 * i + 1], arr[3 * i + 2]);
  const bary = THREE.Triangle.getBarycoord(hit.point, P(pos.array, a), P(pos.array, b), P(pos.array, c), new THREE.Vector3());
  const rest = P(restPositions, a).multiplyScalar(bary.x).add(P(restPositions, b).multiplyScalar(bary.y)).add(P(restPositions, c).multiplyScalar(bary.z));
  const ball = { center: rest.toArray(), radius: parseFloat($('handle-radius').value) * state.diagonal };
  if (handlesPending) return; // the previous handle set is still being prepared
  if (ev.shiftKey && active >= 0) {
    handles[active].balls.push(ball);
    handles[active].fresh = true;
  } else {
    handles.push({ balls: [ball], matrix: new THREE.Matrix4(), fresh: true });
    active = handles.length - 1;
  }
  undoOnHandles = true;
  drawHandles();
  sendHandles();
}
function selectHandle(i) {
  active = i;
  placeGizmo(); drawHandles();
}
// Removes the selected handle; the others keep their targets (an undoable step, as a pick is).
function deleteHandle() {
  if (active < 0 || handlesPending || state.busy) return;
  handles.splice(active, 1);
  active = handles.length - 1;
  state.handles = handles.length;
  undoOnHandles = true;
  placeGizmo(); drawHandles();
  sendHandles();
  if (!handles.length) { pushUndo(); undoOnHandles = false; state.maxDisplacement = 0; $('deform-info').textContent = 'no handles'; }
}
$('delete-handle').onclick = deleteHandle;
// Keyboard shortcuts, as in other editors; not while typing in a field.
window.addEventListener('keydown', (ev) => {
  if (ev.target.closest && ev.target.closest('input, select, textarea')) return;
  const k = ev.key.toLowerCase();
  if ((ev.ctrlKey || ev.metaKey) && k === 'z') { (ev.shiftKey ? $('redo') : $('undo')).click(); ev.preventDefault(); }
  else if ((ev.ctrlKey || ev.metaKey) && k === 'y') { $('redo').click(); ev.preventDefault(); }
  else if (ev.ctrlKey || ev.metaKey || ev.altKey) return;
  else if (k === 'delete' || k === 'backspace') { deleteHandle(); ev.preventDefault(); }
  else if (k === 'escape') selectHandle(-1);
  else if (k === 'g' || k === 't') { $('gizmo-translate').checked = true; gizmo.setMode('translate'); }
  else if (k === 'r') { $('gizmo-rotate').checked = true; gizmo.setMode('rotate'); }
});
let downAt = null;
renderer.domElement.addEventListener('pointerdown', (ev) => { downAt = gizmo.axis ? null : [ev.clientX, ev.clientY]; });
renderer.domElement.addEventListener('pointerup', (ev) => {
  if (downAt && Math.hypot(ev.clientX - downAt[0], ev.clientY - downAt[1]) < 4 && !gizmo.dragging) pick(ev);
  downAt = null;
});

function onGizmoMove() {
  if (active < 0) return;
  const h = handles[active];
  gizmoTarget.updateMatrixWorld();
  h.matrix.copy(gizmoTarget.matrixWorld).multiply(new THREE.Matrix4().makeTranslation(restCentroid(h).negate()));
  drawHandles();
  requestFrame();
}
// One drag request in flight at a time; moves meanwhile only mark a frame as wanted, and the
// newest gizmo pose is sent as soon as the previous frame's positions arrive, before they are
// drawn (the server also drops stale requests).
function requestFrame() {
  if (!handles.length) return;
  if (inFlight || handlesPending) { wantFrame = true; return; }
  inFlight = true; wantFrame = false;
  seq = (seq + 1) >>> 0;
  sentAt.set(seq, performance.now());
  send({ type: 'drag', seq, transforms: transformsArray(), normals: !material.flatShading });
}
let releaseWanted = false;
function endDrag() {
  pushUndo();
  releaseWanted = true;
  if (!inFlight && !wantFrame) { send({ type: 'release' }); releaseWanted = false; }
}

// A deformation frame: copy to the CPU shape, upload the positions, draw. Each stage is timed;
// with the server's timestamps (same machine clock) the frame splits into request transfer,
// server queue / solve / encode, reply transfer, decode, GPU upload and render.
const epoch = (t) => performance.timeOrigin + t;
function onFrame(head, pos, normals, tRecv) {
  const t0 = sentAt.get(head.seq);
  sentAt.delete(head.seq);
  for (const k of sentAt.keys()) if (k < head.seq) sentAt.delete(k);
  const attr = geometry && geometry.getAttribute('position');
  if (!attr || attr.array.length !== pos.length || !gpuPositions) { if (t0 !== undefined) inFlight = false; return; }
  attr.array.set(pos);
  const tDecoded = performance.now();
  // Pipelined: the newest pose goes out before this frame is drawn, so the server solves it while
  // the page uploads and draws, and the time between drawn frames is the slower of the two rather
  // than their sum. Still one request in flight: poses that go stale meanwhile are dropped.
  if (t0 !== undefined) {
    inFlight = false;
    if (wantFrame) requestFrame();
  }
  gl.bindBuffer(gl.ARRAY_BUFFER, gpuPositions);
  gl.bufferSubData(gl.ARRAY_BUFFER, 0, pos);
  if (normals) { gl.bindBuffer(gl.ARRAY_BUFFER, gpuNormals); gl.bufferSubData(gl.ARRAY_BUFFER, 0, normals); }
  gpuSync();
  const tUploaded = performance.now();
  renderQueued = false;
  renderer.render(scene, camera);
  gpuSync();
  const tDrawn = performance.now();
  state.meshVersion++;
  if (t0 !== undefined) {
    const dt = tDrawn - t0;
    state.lastFrameMs = dt;
    state.lastSolveMs = head.solveMs;
    state.framesReceived++;
    state.frameTimes.push(dt);
    const server = head.queueMs + head.solveMs + head.encodeMs;
    state.frameLog.push({
      seq: head.seq, total: dt, drawnAt: tDrawn,
      request: head.receivedAt - epoch(t0), queue: head.queueMs, solve: head.solveMs, encode: head.encodeMs,
      reply: epoch(tRecv) - head.sentAt, server, transfer: tRecv - t0 - server,
      decode: tDecoded - tRecv, upload: tUploaded - tDecoded, render: tDrawn - tUploaded,
    });
    if (state.frameLog.length > 2000) state.frameLog.shift();
    if (state.frameTimes.length > 1000) state.frameTimes.shift();
    const recent = state.frameTimes.slice(-60).sort((a, b) => a - b);
    state.medianFrameMs = recent[Math.floor(recent.length / 2)];
    updateHud();
  }
  if (wantFrame && !inFlight) requestFrame();
  else if (releaseWanted && !inFlight) { send({ type: 'release' }); releaseWanted = false; }
}
function updateHud() {
  const f = state.lastFrameMs == null ? 'frame —' :
    `frame ${state.lastFrameMs.toFixed(1)} ms (median ${state.medianFrameMs.toFixed(1)}, ${(1000 / state.medianFrameMs).toFixed(0)} fps) · solve ${state.lastSolveMs.toFixed(1)} ms`;
  $('frame-time').textContent = f + (state.gridCell ? ` · grid ${state.gridCell}` : '');
}
function onDeformed(m) {
  if (!geometry) return;
  state.symmetryResidual = m.residual;
  state.restResidual = m.rest_residual;
  state.released++;
  const pos = geometry.getAttribute('position').array;
  let maxd = 0;
  for (let i = 0; i < pos.length; i += 3) {
    const d = Math.hypot(pos[i] - restPositions[i], pos[i + 1] - restPositions[i + 1], pos[i + 2] - restPositions[i + 2]);
    if (d > maxd) maxd = d;
  }
  state.maxDisplacement = maxd / (state.diagonal || 1);
  $('deform-info').textContent = `${count(state.handles, 'handle')}; largest move ${(state.maxDisplacement * 100).toFixed(1)}% of the diagonal\n` +
    (m.residual == null ? 'no symmetry annotation' : `symmetry residual ${m.residual.toExponential(2)} (rest ${m.rest_residual.toExponential(2)})`) +
    `\nhandles within ${(100 * m.handle_error).toFixed(2)}% of the diagonal of their targets, solve ${m.solve_ms.toFixed(1)} ms` +
    // Handles are soft: one the symmetries hold back lags its drag (as `motif deform` warns).
    (m.handle_error > HANDLE_LAG && m.residual != null
      ? `\nthe symmetries do not allow this motion: they are kept exact, and the handles lag behind (reset, or drag symmetric handles)`
      : '');
  followDeformation();
}
// The box and grid follow the deformed shape; the detections, found on the undeformed input,
// are hidden while it is deformed rather than left floating where the model was.
const isDeformed = () => state.maxDisplacement > 1e-9;
function followDeformation() {
  geometry.computeBoundingBox();
  drawBox();
  const deformed = isDeformed();
  overlays.detections.visible = $('show-detections').checked && !deformed;
  $('show-detections').title = deformed ? 'hidden while the model is deformed (Reset shows them again)' : '';
  requestRender();
}
// Puts the handles and the size of a history step back, each only when it differs from what
// is shown (undoing a resize does not refactor the deformation, and the reverse).
function applyState(s) {
  if (handlesKey(s.handles) !== handlesKey(handlesSnapshot())) applyHandles(s.handles);
  // A size typed or released just before is not committed over the step undone to.
  committing = null;
  const now = retargetObject ? shownSteps : null;
  if (JSON.stringify(s.steps) === JSON.stringify(now)) return;
  if (s.steps === null) { clearResized(); return; }
  s.steps.forEach((v, k) => { if ($(`step-${k}`)) { $(`step-${k}`).value = v; $(`step-${k}-value`).value = v; } });
  sendRetarget();
}
function applyHandles(s) {
  handles = s.map((h) => ({ balls: h.balls.map((b) => ({ ...b })), matrix: h.matrix.clone() }));
  active = handles.length - 1;
  placeGizmo(); drawHandles(); sendHandles();
  if (handles.length) releaseWanted = true;
  else state.maxDisplacement = 0;
}
$('undo').onclick = () => {
  if (!undoStack.length) return;
  redoStack.push(undoStack.pop());
  applyState(historyTop());
  updateUndo();
};
$('redo').onclick = () => {
  if (!redoStack.length) return;
  const s = redoStack.pop();
  undoStack.push(s);
  applyState(s);
  updateUndo();
};
$('reset').onclick = () => { applyHandles([]); pushUndo(); state.maxDisplacement = 0; $('deform-info').textContent = 'no handles'; };
// The name's extension decides the format; the list follows it, and a name without one gets the
// list's format.
const extOf = (p) => { const m = /\.([^.\/]+)$/.exec(p.trim()); return m ? m[1].toLowerCase() : ''; };
$('export-format').onchange = () => { $('export-path').value = $('export-path').value.trim().replace(/\.[^.\/]*$/, '') + '.' + $('export-format').value; };
$('export-path').oninput = () => {
  const e = extOf($('export-path').value);
  if ([...$('export-format').options].some((o) => o.value === e)) $('export-format').value = e;
};
$('export').onclick = () => {
  if (!extOf($('export-path').value) && $('export-path').value.trim()) $('export-path').value = `${$('export-path').value.trim()}.${$('export-format').value}`;
  setBusy('export'); send({ type: 'export', path: $('export-path').value, source: 'deformed', download: true, overwrite: $('overwrite').checked });
};

// ---------------------------------------------------------------------------------------------
// Resize
let retargetSeq = 0;
// The steps of the resized model on screen: a size the server refuses puts the sliders back.
let shownSteps = [0, 0, 0];
function restoreSteps() {
  shownSteps.forEach((v, k) => { if ($(`step-${k}`)) { $(`step-${k}`).value = v; $(`step-${k}-value`).value = v; } });
}
function onOffsets(m) {
  shownSteps = [0, 0, 0];
  clearResized(false);
  // The resized model is gone and the sliders are new: no step of the history shows a size.
  for (const e of [...undoStack, ...redoStack, historyBase]) e.steps = null;
  clearGroup(overlays.offsets);
  state.offsets = { principal: m.principal.length, cells: m.cells, minSteps: m.min_steps, summary: m.summary };
  state.cells = m.cells; state.totalCells = m.cells.reduce((a, b) => a * b, 1);
  const steps = $('steps');
  steps.replaceChildren();
  // The verdict's summary says "no repetition" itself.
  if (!m.principal.length) { $('resize-info').textContent = m.summary; requestRender(); return; }
  // From just outside the box's lower corner, drawn over the model: from the corner itself
  // they ran inside the model and could only be seen in wireframe.
  const origin = geometry.boundingBox.min.clone().subScalar(0.04 * (state.diagonal || 1));
  m.principal.forEach((o, k) => {
    const v = new THREE.Vector3(...o);
    const arrow = new THREE.ArrowHelper(v.clone().normalize(), origin, v.length(), palette[k], v.length() * 0.25, v.length() * 0.12);
    arrow.traverse((c) => { if (c.material) { c.material.depthTest = false; c.renderOrder = 10; } });
    overlays.offsets.add(arrow);
    const row = document.createElement('div');
    row.className = 'row';
    // From the fewest cells a resize keeps (the server's bound) to twice the model's cells, at
    // least 6 and at most 64 (the server's limit); the number field takes any value in range.
    const lo = Math.max(-64, (m.min_steps && m.min_steps[k] != null) ? m.min_steps[k] : -3);
    const hi = Math.min(64, Math.max(6, 2 * (m.cells[k] || 0)));
    row.innerHTML = `<label title="cells to add along this offset (negative removes)">offset ${k}: ${v.length().toPrecision(3)} units, ${m.cells[k]} ${m.cells[k] === 1 ? 'cell' : 'cells'} <input type="range" id="step-${k}" min="${lo}" max="${hi}" step="1" value="0"><input type="number" id="step-${k}-value" min="${lo}" max="${hi}" step="1" value="0" style="width:4em"></label>`;
    steps.append(row);
  });
  m.principal.forEach((_, k) => {
    $(`step-${k}`).oninput = () => { $(`step-${k}-value`).value = $(`step-${k}`).value; sendRetarget(); };
    // Releasing the slider makes the size one step of the undo history.
    $(`step-${k}`).onchange = commitSize;
    $(`step-${k}-value`).onchange = () => {
      const f = $(`step-${k}-value`);
      const v = Math.max(Number(f.min), Math.min(Number(f.max), Math.round(Number(f.value) || 0)));
      f.value = v; $(`step-${k}`).value = v;
      sendRetarget();
      commitSize();
    };
  });
  $('resize-warning').hidden = true;
  $('resize-info').textContent = `${m.principal.length} principal ${m.principal.length === 1 ? 'offset' : 'offsets'}; cells ${m.cells.join(' × ')}; ${m.ms.toFixed(0)} ms\n${m.summary}`;
  requestRender();
}
// The size the user settled on (slider released, number typed) enters the undo history once
// the server has shown it; a size the server refuses never does.
let committing = null;
const slidersSteps = () => [0, 1, 2].map((k) => ($(`step-${k}`) ? parseInt($(`step-${k}`).value, 10) : 0));
function commitSize() {
  committing = slidersSteps();
  maybeCommit();
}
function maybeCommit() {
  if (!committing || !retargetObject || JSON.stringify(committing) !== JSON.stringify(shownSteps)) return;
  committing = null;
  if (JSON.stringify(historyTop().steps) !== JSON.stringify(shownSteps)) pushUndo();
}
// Removes the resized model (undo back past the first resize, offsets found again): the
// original shows again with its handles, and the sliders go back to 0.
// Replies to resize requests sent before this sequence number are dropped: a resize undone
// while its reply was on the way must not come back.
let ignoreBelow = 0;
function clearResized(say = true) {
  ignoreBelow = retargetSeq + 1; committing = null;
  if (!retargetObject) return;
  scene.remove(retargetObject); retargetObject.geometry.dispose(); retargetObject = null;
  shownSteps = [0, 0, 0]; restoreSteps();
  if (object) object.visible = true;
  overlays.handles.visible = true; placeGizmo();
  if (state.offsets) { state.cells = state.offsets.cells; state.totalCells = state.offsets.cells.reduce((a, b) => a * b, 1); }
  state.retargetVersion++; state.resizedSteps = null;
  $('resize-warning').hidden = true;
  if (say) $('resize-info').textContent = 'back to the original size (Redo resizes again)';
  requestRender();
}
function sendRetarget() {
  const s = [0, 1, 2].map((k) => ($(`step-${k}`) ? parseInt($(`step-${k}`).value, 10) : 0));
  retargetSeq++;
  send({ type: 'retarget', seq: retargetSeq, steps: s });
}
function onRetargetedMesh(pos, index, m) {
  if (m.seq < ignoreBelow) return;
  if (retargetObject) { scene.remove(retargetObject); retargetObject.geometry.dispose(); }
  const g = new THREE.BufferGeometry();
  g.setAttribute('position', new THREE.BufferAttribute(new Float32Array(pos), 3));
  g.setIndex(new THREE.BufferAttribute(new Uint32Array(index), 1));
  g.computeVertexNormals();
  retargetObject = new THREE.Mesh(g, new THREE.MeshStandardMaterial({ color: 0xd9b98c, roughness: 0.7, flatShading: true, side: THREE.DoubleSide }));
  scene.add(retargetObject);
  // A resized model that outgrows the view is framed again (a shelf grown by several cells ran
  // off the screen); small changes keep the user's camera.
  g.computeBoundingSphere();
  const sph = g.boundingSphere;
  if (sph.radius > 1.15 * framedRadius || sph.center.distanceTo(orbit.target) > 0.5 * framedRadius) frameCamera(sph);
  object.visible = $('show-original').checked;
  state.cells = m.cells; state.totalCells = m.total_cells; state.retargetVertices = m.vertices; state.retargetVersion++;
  shownSteps = m.steps.slice();
  state.resizedSteps = shownSteps.slice();
  maybeCommit();
  const n = m.cells.length;
  $('resize-info').textContent = `steps ${m.steps.slice(0, n).join(', ')}: cells ${m.cells.join(' × ')}${n > 1 ? ` = ${m.total_cells}` : ''}\n${m.vertices} vertices, ${m.triangles} triangles, ${m.ms.toFixed(0)} ms` +
    // The resize starts from the undeformed model.
    (isDeformed() ? '\nresized from the undeformed model: the deformation is not part of it' : '');
  // The handles belong to the original, which the resized model hides.
  overlays.handles.visible = object.visible; if (!object.visible) gizmo.detach();
  // Seams of infinite cost: the result is open there, and must not look like a success.
  $('resize-warning').textContent = m.warning || '';
  $('resize-warning').hidden = !m.warning;
  reveal(m.warning ? $('resize-warning') : $('resize-info'));
  requestRender();
}
$('show-original').onchange = () => {
  if (object) object.visible = $('show-original').checked || !retargetObject;
  overlays.handles.visible = !object || object.visible;
  if (object && object.visible) placeGizmo(); else gizmo.detach();
  requestRender();
};
// Leaving or reloading the page loses the deformation and the resize: the browser asks first.
window.addEventListener('beforeunload', (ev) => {
  if (isDeformed() || retargetObject) { ev.preventDefault(); ev.returnValue = ''; }
});
$('find-offsets').onclick = () => { setBusy('offsets'); send({ type: 'offsets' }); };
$('export-resized').onclick = () => {
  // The server keeps the last resize; after an undo back to the original size none is shown.
  if (!retargetObject) { message('nothing resized yet: move a slider under Resize first (after Find offsets)', true); reveal($('messages')); return; }
  setBusy('export'); send({ type: 'export', path: $('export-resized-path').value, source: 'retargeted', download: true, overwrite: $('overwrite').checked }); };

// Test helpers: where a world point appears on screen, and a rest vertex.
window.motif.project = (p) => {
  const v = new THREE.Vector3(...p).project(camera);
  const rect = renderer.domElement.getBoundingClientRect();
  return { x: rect.left + ((v.x + 1) / 2) * rect.width, y: rect.top + ((1 - v.y) / 2) * rect.height };
};
window.motif.restVertex = (i) => [restPositions[3 * i], restPositions[3 * i + 1], restPositions[3 * i + 2]];
window.motif.activeHandle = () => active;
window.motif.handleScreen = (i) => window.motif.project(new THREE.Vector3(...handles[i].balls[0].center).applyMatrix4(handles[i].matrix).toArray());
window.motif.gizmoScreen = () => (active >= 0 ? window.motif.project(gizmoTarget.position.toArray()) : null);
// The current (deformed) shape as a plain array, and the surface point under a screen position.
window.motif.positions = () => Array.from(geometry.getAttribute('position').array);
window.motif.resizedShown = () => ({ resized: !!retargetObject && retargetObject.parent === scene, original: !!object && object.visible });
window.motif.surfaceAt = (x, y) => {
  if (!pickMesh) return null;
  const rect = renderer.domElement.getBoundingClientRect();
  const ray = new THREE.Raycaster();
  ray.setFromCamera(new THREE.Vector2(((x - rect.left) / rect.width) * 2 - 1, -((y - rect.top) / rect.height) * 2 + 1), camera);
  geometry.computeBoundingSphere();
  const hit = ray.intersectObject(pickMesh, false)[0];
  return hit ? hit.point.toArray() : null;
};

// Enter in a path field does what its button does.
for (const [field, button] of [['open-path', 'open-btn'], ['annotation-path', 'load-annotation'], ['detections-path', 'load-detections'], ['export-path', 'export'], ['export-resized-path', 'export-resized']]) {
  $(field).addEventListener('keydown', (ev) => { if (ev.key === 'Enter' && !$(button).disabled) { ev.preventDefault(); $(button).click(); } });
}
setBusy(null);
resize();
connect();
