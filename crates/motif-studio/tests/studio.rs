//! The studio server through a real WebSocket client: hostile and oversized messages, path
//! escapes, cancellation and cleanup, detections, resizing, and 20 concurrent clients each
//! solving a real deformation.

use std::path::Path;
use std::time::Duration;

use futures_util::{SinkExt, StreamExt};
use motif_studio::protocol::{FRAME_HEADER_BYTES, Limits};
use motif_studio::{ServerMessage, SessionCounter, Studio, StudioOptions};
use serde_json::json;
use tokio::net::TcpStream;
use tokio_tungstenite::tungstenite::Message;
use tokio_tungstenite::tungstenite::client::IntoClientRequest;
use tokio_tungstenite::{MaybeTlsStream, WebSocketStream};

type Ws = WebSocketStream<MaybeTlsStream<TcpStream>>;

/// Limits small enough to test: 4 KiB text, 256 KiB uploads.
const TEST_LIMITS: Limits = Limits { max_text_bytes: 4096, max_upload_bytes: 256 * 1024, max_sessions: 64 };

struct Server {
    url: String,
    sessions: SessionCounter,
    _dir: tempfile::TempDir,
    root: std::path::PathBuf,
}

async fn start() -> Server {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("root");
    std::fs::create_dir(&root).unwrap();
    let ex = motif_core::procedural::generate("fan", 1).unwrap();
    motif_core::io::write_mesh(&root.join("fan.obj"), &ex.mesh).unwrap();
    motif_core::io::write_mesh(&dir.path().join("outside.obj"), &ex.mesh).unwrap();
    let options = StudioOptions { root: root.clone(), limits: TEST_LIMITS, ..Default::default() };
    let studio = Studio::bind(options).await.unwrap();
    let url = format!("ws://{}/ws", studio.local_addr().unwrap());
    let sessions = studio.sessions();
    tokio::spawn(studio.serve());
    Server { url, sessions, _dir: dir, root }
}

async fn connect(url: &str) -> Ws {
    let (mut ws, _) = tokio_tungstenite::connect_async(url).await.unwrap();
    match next_text(&mut ws).await {
        ServerMessage::Hello { .. } => {}
        other => panic!("expected hello, got {other:?}"),
    }
    ws
}

enum Reply {
    Text(ServerMessage),
    Binary(Vec<u8>),
    Closed(Option<u16>),
}

async fn next(ws: &mut Ws) -> Reply {
    loop {
        match ws.next().await {
            Some(Ok(Message::Text(t))) => return Reply::Text(serde_json::from_str(t.as_str()).unwrap()),
            Some(Ok(Message::Binary(b))) => return Reply::Binary(b.to_vec()),
            Some(Ok(Message::Close(f))) => return Reply::Closed(f.map(|f| u16::from(f.code))),
            Some(Ok(_)) => continue,
            Some(Err(_)) | None => return Reply::Closed(None),
        }
    }
}

/// The next text message that is not a progress report.
async fn next_text(ws: &mut Ws) -> ServerMessage {
    loop {
        match next(ws).await {
            Reply::Text(ServerMessage::Progress { .. }) => continue,
            Reply::Text(m) => return m,
            Reply::Binary(_) => continue,
            Reply::Closed(c) => panic!("connection closed ({c:?})"),
        }
    }
}

async fn send(ws: &mut Ws, v: serde_json::Value) {
    ws.send(Message::Text(v.to_string().into())).await.unwrap();
}

/// Opens a generated example; returns its vertex count (the model's binary frame is consumed).
async fn open_example(ws: &mut Ws, name: &str) -> usize {
    send(ws, json!({"type": "example", "name": name})).await;
    let n = match next_text(ws).await {
        ServerMessage::Model { vertices, .. } => vertices,
        other => panic!("expected model, got {other:?}"),
    };
    match next(ws).await {
        Reply::Binary(b) => assert_eq!(u32::from_le_bytes(b[8..12].try_into().unwrap()) as usize, n),
        _ => panic!("expected the model's geometry"),
    }
    n
}

fn expect_error(m: ServerMessage, needle: &str) {
    match m {
        ServerMessage::Error { message, .. } => {
            assert!(message.contains(needle), "error {message:?} should mention {needle:?}")
        }
        other => panic!("expected an error mentioning {needle:?}, got {other:?}"),
    }
}

fn positions(frame: &[u8]) -> Vec<f32> {
    frame[FRAME_HEADER_BYTES..].chunks_exact(4).map(|c| f32::from_le_bytes(c.try_into().unwrap())).collect()
}

/// The next binary message, which must be a deformation frame with sequence number `seq`.
async fn next_frame(ws: &mut Ws, seq: u32) -> Vec<f32> {
    let frame = match next(ws).await {
        Reply::Binary(b) => b,
        Reply::Text(m) => panic!("expected a frame, got {m:?}"),
        Reply::Closed(_) => panic!("closed"),
    };
    assert_eq!(u32::from_le_bytes(frame[0..4].try_into().unwrap()), 2);
    assert_eq!(u32::from_le_bytes(frame[4..8].try_into().unwrap()), seq);
    positions(&frame)
}

/// The `handles` reply (its transforms); the frame that follows it is consumed and returned.
async fn handles_reply(ws: &mut Ws, count: usize) -> (Vec<[[f64; 4]; 4]>, Vec<f32>) {
    let transforms = match next_text(ws).await {
        ServerMessage::Handles { handles, samples, transforms, .. } => {
            assert_eq!(handles, count);
            assert!(samples.iter().all(|&k| k > 0), "{samples:?}");
            transforms
        }
        other => panic!("expected handles, got {other:?}"),
    };
    (transforms, next_frame(ws, 0).await)
}

fn translation(t: [f64; 3]) -> [[f64; 4]; 4] {
    [[1.0, 0.0, 0.0, t[0]], [0.0, 1.0, 0.0, t[1]], [0.0, 0.0, 1.0, t[2]], [0.0, 0.0, 0.0, 1.0]]
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn hostile_messages_are_answered_and_the_server_keeps_serving() {
    let s = start().await;
    let mut ws = connect(&s.url).await;
    let hostile = [
        ("not json", "bad message"),
        ("{\"type\":\"launch_missiles\"}", "bad message"),
        ("{\"type\":\"open\"}", "bad message"),
        ("{\"type\":\"open\",\"path\":17}", "bad message"),
        ("{\"type\":\"retarget\",\"seq\":-1,\"steps\":[1]}", "bad message"),
        ("[]", "bad message"),
        ("{\"type\":\"drag\",\"seq\":1,\"transforms\":[[[1e999]]]}", "bad message"),
    ];
    for (text, needle) in hostile {
        ws.send(Message::Text(text.into())).await.unwrap();
        expect_error(next_text(&mut ws).await, needle);
    }
    // Requests in the wrong order get explanations.
    send(&mut ws, json!({"type": "detect_symmetry"})).await;
    expect_error(next_text(&mut ws).await, "open a model first");
    send(&mut ws, json!({"type": "drag", "seq": 1, "transforms": []})).await;
    expect_error(next_text(&mut ws).await, "pick handles");
    send(&mut ws, json!({"type": "retarget", "seq": 1, "steps": [1, 0, 0]})).await;
    expect_error(next_text(&mut ws).await, "principal offsets first");
    send(&mut ws, json!({"type": "example", "name": "no-such-shape"})).await;
    expect_error(next_text(&mut ws).await, "unknown example");
    // Bad handles: a negative radius, too many handles, a handle that selects nothing.
    let n = open_example(&mut ws, "fan").await;
    assert!(n > 0);
    send(
        &mut ws,
        json!({"type": "set_handles", "handles": [{"balls": [{"center": [0, 0, 0], "radius": -1.0}]}]}),
    )
    .await;
    expect_error(next_text(&mut ws).await, "radii positive");
    send(
        &mut ws,
        json!({"type": "set_handles", "handles": [{"balls": [{"center": [90, 90, 90], "radius": 0.01}]}]}),
    )
    .await;
    assert!(matches!(next_text(&mut ws).await, ServerMessage::Error { .. }));
    let many: Vec<_> = (0..65).map(|_| json!({"balls": [{"center": [0, 0, 0], "radius": 0.1}]})).collect();
    let text = json!({"type": "set_handles", "handles": many}).to_string();
    assert!(text.len() < TEST_LIMITS.max_text_bytes);
    ws.send(Message::Text(text.into())).await.unwrap();
    expect_error(next_text(&mut ws).await, "at most 64");
    // Malformed uploads: a truncated header, a name longer than the message, an unknown format,
    // a file that does not parse.
    for bytes in [
        vec![1u8, 0],
        vec![200, 0, 0, 0, b'a'],
        upload("x.xyz", b"1 2 3"),
        upload("x.obj", b"v 1 2\nf 1 2 3\n"),
    ] {
        ws.send(Message::Binary(bytes.into())).await.unwrap();
        assert!(matches!(next_text(&mut ws).await, ServerMessage::Error { .. }));
    }
    // Oversized text: an error reply, and the same connection keeps working.
    let big = format!("{{\"type\":\"open\",\"path\":\"{}\"}}", "a".repeat(TEST_LIMITS.max_text_bytes));
    ws.send(Message::Text(big.into())).await.unwrap();
    expect_error(next_text(&mut ws).await, "text messages are limited");
    assert_eq!(open_example(&mut ws, "fan").await, n);
    // A valid upload works.
    let ex = motif_core::procedural::generate("chair", 1).unwrap();
    let obj = s.root.join("chair.obj");
    motif_core::io::write_mesh(&obj, &ex.mesh).unwrap();
    ws.send(Message::Binary(upload("chair.obj", &std::fs::read(&obj).unwrap()).into())).await.unwrap();
    match next_text(&mut ws).await {
        ServerMessage::Model { vertices, name, .. } => {
            assert_eq!(vertices, ex.mesh.num_vertices());
            assert_eq!(name, "chair.obj");
        }
        other => panic!("expected the uploaded model, got {other:?}"),
    }
    // Over the upload limit: an error naming the limit, and the same connection keeps working.
    let over = upload("big.obj", &vec![b' '; TEST_LIMITS.max_upload_bytes + 64 * 1024]);
    ws.send(Message::Binary(over.into())).await.unwrap();
    expect_error(next_text(&mut ws).await, &format!("the limit is {} bytes", TEST_LIMITS.max_upload_bytes));
    assert_eq!(open_example(&mut ws, "fan").await, n);
    // Over the transport limit (twice the upload limit): that connection is closed with 1009, the
    // server keeps serving.
    let huge = vec![0u8; 2 * TEST_LIMITS.max_upload_bytes + 64 * 1024];
    let _ = ws.send(Message::Binary(huge.into())).await;
    loop {
        match next(&mut ws).await {
            Reply::Closed(code) => {
                assert!(code.is_none() || code == Some(1009), "close code {code:?}");
                break;
            }
            _ => continue,
        }
    }
    let mut again = connect(&s.url).await;
    assert_eq!(open_example(&mut again, "fan").await, n);
}

fn upload(name: &str, bytes: &[u8]) -> Vec<u8> {
    let mut v = (name.len() as u32).to_le_bytes().to_vec();
    v.extend_from_slice(name.as_bytes());
    v.extend_from_slice(bytes);
    v
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn files_outside_the_root_cannot_be_read_or_written() {
    let s = start().await;
    let mut ws = connect(&s.url).await;
    let outside = s.root.parent().unwrap().join("outside.obj");
    #[cfg(unix)]
    {
        std::os::unix::fs::symlink(&outside, s.root.join("link.obj")).unwrap();
        std::os::unix::fs::symlink(s.root.parent().unwrap(), s.root.join("up")).unwrap();
    }
    let mut escapes = vec![
        "../outside.obj".to_string(),
        outside.display().to_string(),
        "./../root/../outside.obj".to_string(),
    ];
    if cfg!(unix) {
        escapes.push("link.obj".to_string());
        escapes.push("up/outside.obj".to_string());
    }
    for p in &escapes {
        send(&mut ws, json!({"type": "open", "path": p})).await;
        expect_error(next_text(&mut ws).await, "outside the studio's root");
        send(&mut ws, json!({"type": "load_detections", "path": p})).await;
        assert!(matches!(next_text(&mut ws).await, ServerMessage::Error { .. }));
    }
    send(&mut ws, json!({"type": "open", "path": "nope.obj"})).await;
    expect_error(next_text(&mut ws).await, "cannot open");
    // Inside the root: open, then every write that leaves it is refused.
    send(&mut ws, json!({"type": "open", "path": "fan.obj"})).await;
    assert!(matches!(next_text(&mut ws).await, ServerMessage::Model { .. }));
    let mut writes = vec![
        "../written.obj".to_string(),
        s.root.parent().unwrap().join("written.obj").display().to_string(),
    ];
    if cfg!(unix) {
        writes.push("up/written.obj".to_string());
        writes.push("link.obj".to_string());
    }
    for p in &writes {
        send(&mut ws, json!({"type": "export", "path": p, "overwrite": true})).await;
        assert!(matches!(next_text(&mut ws).await, ServerMessage::Error { .. }), "{p}");
    }
    assert!(!s.root.parent().unwrap().join("written.obj").exists());
    // The input is never overwritten, even when asked to.
    let before = std::fs::read(s.root.join("fan.obj")).unwrap();
    send(&mut ws, json!({"type": "export", "path": "fan.obj", "overwrite": true})).await;
    expect_error(next_text(&mut ws).await, "refusing to overwrite");
    assert_eq!(std::fs::read(s.root.join("fan.obj")).unwrap(), before);
    // A write inside the root works and is read back.
    send(&mut ws, json!({"type": "export", "path": "copy.ply"})).await;
    match next_text(&mut ws).await {
        ServerMessage::Saved { paths, .. } => assert_eq!(paths, vec!["copy.ply".to_string()]),
        other => panic!("expected saved, got {other:?}"),
    }
    send(&mut ws, json!({"type": "export", "path": "copy.ply"})).await;
    expect_error(next_text(&mut ws).await, "already exists");
    send(&mut ws, json!({"type": "open", "path": "copy.ply"})).await;
    assert!(matches!(next_text(&mut ws).await, ServerMessage::Model { .. }));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn pages_from_other_origins_are_refused() {
    let s = start().await;
    let mut req = s.url.as_str().into_client_request().unwrap();
    req.headers_mut().insert("Origin", "http://evil.example".parse().unwrap());
    assert!(tokio_tungstenite::connect_async(req).await.is_err());
    let mut req = s.url.as_str().into_client_request().unwrap();
    let host = req.headers()["Host"].to_str().unwrap().to_string();
    req.headers_mut().insert("Origin", format!("http://{host}").parse().unwrap());
    assert!(tokio_tungstenite::connect_async(req).await.is_ok());
    // DNS rebinding: a foreign host name pointing at this machine.
    let mut req = s.url.as_str().into_client_request().unwrap();
    req.headers_mut().insert("Host", "evil.example".parse().unwrap());
    assert!(tokio_tungstenite::connect_async(req).await.is_err());
}

/// One client: opens the fan, fixes its hub, lifts a blade tip and checks the frame and the
/// symmetry residual.
async fn deform_client(url: String, lift: f64) -> f64 {
    let mut ws = connect(&url).await;
    let n = open_example(&mut ws, "fan").await;
    send(
        &mut ws,
        json!({"type": "set_handles", "handles": [
            {"balls": [{"center": [0.0, 0.0, 0.0], "radius": 0.06}]},
            {"balls": [{"center": [0.3, 0.0, 0.0], "radius": 0.04}]}]}),
    )
    .await;
    let (targets, rest) = handles_reply(&mut ws, 2).await;
    assert_eq!(targets, vec![translation([0.0; 3]); 2], "new handles start where they are");
    assert_eq!(rest.len(), 3 * n);
    let transforms = [translation([0.0; 3]), translation([0.0, 0.0, lift])];
    send(&mut ws, json!({"type": "drag", "seq": 7, "transforms": transforms})).await;
    let p = next_frame(&mut ws, 7).await;
    assert_eq!(p.len(), 3 * n);
    let ex = motif_core::procedural::generate("fan", 1).unwrap();
    let moved = ex
        .mesh
        .positions
        .iter()
        .enumerate()
        .map(|(i, r)| (0..3).map(|k| (p[3 * i + k] as f64 - r[k]).abs()).fold(0.0, f64::max))
        .fold(0.0, f64::max);
    assert!(moved > 0.5 * lift, "the blade should follow the handle: moved {moved}");
    send(&mut ws, json!({"type": "release"})).await;
    match next_text(&mut ws).await {
        ServerMessage::Deformed { residual: Some(r), .. } => r,
        other => panic!("expected deformed, got {other:?}"),
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn twenty_concurrent_clients_each_deform() {
    let s = start().await;
    let tasks: Vec<_> =
        (0..20).map(|i| tokio::spawn(deform_client(s.url.clone(), 0.02 + 0.002 * i as f64))).collect();
    for t in tasks {
        let residual = t.await.unwrap();
        assert!(residual < 1e-9, "symmetry residual {residual}");
    }
    wait_for_sessions(&s.sessions, 0).await;
}

async fn wait_for_sessions(c: &SessionCounter, n: usize) {
    // Sessions are freed asynchronously after the socket closes; give it up to a minute.
    for _ in 0..600 {
        if c.get() == n {
            return;
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    assert_eq!(c.get(), n, "sessions still held");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn long_computations_cancel_and_disconnects_free_sessions() {
    let s = start().await;
    let mut ws = connect(&s.url).await;
    open_example(&mut ws, "gear").await;
    send(&mut ws, json!({"type": "detect_symmetry"})).await;
    send(&mut ws, json!({"type": "cancel"})).await;
    // Cancelled, unless detection already finished before the cancel arrived.
    match next_text(&mut ws).await {
        ServerMessage::Cancelled { job } => assert_eq!(job, "detect_symmetry"),
        ServerMessage::Annotation { .. } => {}
        other => panic!("expected cancelled, got {other:?}"),
    }
    // The session still works after a cancel.
    send(&mut ws, json!({"type": "detect_symmetry"})).await;
    match next_text(&mut ws).await {
        ServerMessage::Annotation { groups, ok, .. } => {
            assert!(ok);
            assert!(groups.iter().any(|g| g.schoenflies == "D17h"), "{groups:?}");
        }
        other => panic!("expected the annotation, got {other:?}"),
    }
    assert_eq!(s.sessions.get(), 1);
    // Leave in the middle of a computation: the session is freed.
    send(&mut ws, json!({"type": "offsets"})).await;
    drop(ws);
    let mut other = connect(&s.url).await;
    open_example(&mut other, "fan").await;
    drop(other);
    wait_for_sessions(&s.sessions, 0).await;
}

/// A resize with seams of infinite cost says so: the gridbeam shelf of the shared data is two
/// cells wide, so growing it in width puts a copy's geometry against empty space at every seam.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_resize_that_cannot_stitch_cleanly_warns() {
    let Some(data) = motif_core::data::shared_data_dir(std::path::Path::new(env!("CARGO_MANIFEST_DIR")))
    else {
        println!("skipping: no shared data found (set MOTIF_DATA)");
        return;
    };
    let s = start().await;
    std::fs::copy(data.join("man-made/mcad_gridbeam_shelf.stl"), s.root.join("gridbeam.stl")).unwrap();
    let mut ws = connect(&s.url).await;
    send(&mut ws, json!({"type": "open", "path": "gridbeam.stl"})).await;
    assert!(matches!(next_text(&mut ws).await, ServerMessage::Model { .. }));
    assert!(matches!(next(&mut ws).await, Reply::Binary(_)));
    send(&mut ws, json!({"type": "offsets"})).await;
    match next_text(&mut ws).await {
        ServerMessage::Offsets { principal, .. } => assert_eq!(principal.len(), 3),
        other => panic!("expected offsets, got {other:?}"),
    }
    send(&mut ws, json!({"type": "retarget", "seq": 1, "steps": [1, 1, 0]})).await;
    match next_text(&mut ws).await {
        ServerMessage::Retargeted { warning, .. } => {
            let w = warning.expect("a warning");
            assert!(w.contains("no seam-consistent stitching") && w.contains("open boundary edges"), "{w}");
            assert!(w.contains("steps 1, 0, 0 stitches cleanly"), "{w}");
        }
        other => panic!("expected retargeted, got {other:?}"),
    }
    assert!(matches!(next(&mut ws).await, Reply::Binary(_)));
    // The steps suggested do stitch without a warning.
    send(&mut ws, json!({"type": "retarget", "seq": 2, "steps": [1, 0, 0]})).await;
    match next_text(&mut ws).await {
        ServerMessage::Retargeted { warning, .. } => assert_eq!(warning, None),
        other => panic!("expected retargeted, got {other:?}"),
    }
    assert!(matches!(next(&mut ws).await, Reply::Binary(_)));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn shelf_grows_by_one_cell_and_exports() {
    let s = start().await;
    let mut ws = connect(&s.url).await;
    open_example(&mut ws, "shelf").await;
    send(&mut ws, json!({"type": "offsets"})).await;
    match next_text(&mut ws).await {
        ServerMessage::Offsets { principal, cells, .. } => {
            assert_eq!(principal.len(), 2);
            assert_eq!(cells, vec![4, 3]);
        }
        other => panic!("expected offsets, got {other:?}"),
    }
    send(&mut ws, json!({"type": "retarget", "seq": 1, "steps": [1, 0, 0]})).await;
    match next_text(&mut ws).await {
        ServerMessage::Retargeted { cells, total_cells, warning, .. } => {
            assert_eq!(cells, vec![5, 3]);
            assert_eq!(total_cells, 15);
            assert_eq!(warning, None, "the shelf stitches cleanly");
        }
        other => panic!("expected retargeted, got {other:?}"),
    }
    assert!(matches!(next(&mut ws).await, Reply::Binary(_)));
    send(&mut ws, json!({"type": "export", "path": "shelf5.glb", "source": "retargeted"})).await;
    assert!(matches!(next_text(&mut ws).await, ServerMessage::Saved { .. }));
    let back = motif_core::io::read_mesh(&s.root.join("shelf5.glb")).unwrap();
    assert!(back.num_vertices() > 0);
}

/// A retargeted export keeps the model's vertex colours: grown along x, a shelf coloured by
/// height comes out coloured by height.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_retargeted_export_keeps_the_vertex_colours() {
    let s = start().await;
    let ex = motif_core::procedural::generate("shelf", 0).unwrap();
    let top = ex.mesh.aabb().unwrap().max[1];
    let red = |p: [f64; 3]| (200.0 * p[1] / top).round() as u8;
    let mut model = motif_core::io::Model::from_mesh(&ex.mesh);
    model.vertices.colors = Some(ex.mesh.positions.iter().map(|&p| [red(p), 40, 90]).collect());
    motif_core::io::write(&s.root.join("coloured.ply"), &model, &Default::default()).unwrap();
    let mut ws = connect(&s.url).await;
    send(&mut ws, json!({"type": "open", "path": "coloured.ply"})).await;
    assert!(matches!(next_text(&mut ws).await, ServerMessage::Model { .. }));
    send(&mut ws, json!({"type": "offsets"})).await;
    assert!(matches!(next_text(&mut ws).await, ServerMessage::Offsets { .. }));
    send(&mut ws, json!({"type": "retarget", "seq": 1, "steps": [1, 0, 0]})).await;
    assert!(matches!(next_text(&mut ws).await, ServerMessage::Retargeted { .. }));
    assert!(matches!(next(&mut ws).await, Reply::Binary(_)));
    send(&mut ws, json!({"type": "export", "path": "grown.ply", "source": "retargeted"})).await;
    assert!(matches!(next_text(&mut ws).await, ServerMessage::Saved { .. }));
    let back = motif_core::io::read(&s.root.join("grown.ply")).unwrap();
    assert!(back.vertices.len() > ex.mesh.num_vertices());
    let colours = back.vertices.colors.expect("the export has the colours");
    for (p, c) in back.vertices.positions.iter().zip(&colours) {
        assert!(c[0].abs_diff(red(*p)) <= 1 && c[1] == 40 && c[2] == 90, "{p:?}: {c:?}");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn detections_load_from_a_result_file() {
    let s = start().await;
    let ex = motif_core::procedural::generate("facade", 1).unwrap();
    motif_core::io::write_mesh(&s.root.join("facade.ply"), &ex.mesh).unwrap();
    let gt = ex.structure.detection_ground_truth("facade.ply");
    std::fs::write(s.root.join("RESULT.json"), gt.to_string()).unwrap();
    std::fs::write(s.root.join("broken.json"), "{\"scene\": 1}").unwrap();
    let mut ws = connect(&s.url).await;
    send(&mut ws, json!({"type": "open", "path": "facade.ply"})).await;
    assert!(matches!(next_text(&mut ws).await, ServerMessage::Model { .. }));
    // Nothing to save before detections are shown.
    send(&mut ws, json!({"type": "save_detections", "path": "saved.json"})).await;
    expect_error(next_text(&mut ws).await, "no detections yet");
    send(&mut ws, json!({"type": "load_detections", "path": "RESULT.json"})).await;
    match next_text(&mut ws).await {
        ServerMessage::Detections { classes, point_class, .. } => {
            assert_eq!(classes.len(), ex.structure.instances.len());
            assert_eq!(point_class.len(), ex.mesh.num_vertices());
            assert!(classes.iter().all(|c| c.points > 0), "{classes:?}");
        }
        other => panic!("expected detections, got {other:?}"),
    }
    // The detections shown are saved as a result that reads back equal; not under a model's
    // extension, and not over the file they were loaded from.
    send(&mut ws, json!({"type": "save_detections", "path": "saved.json"})).await;
    match next_text(&mut ws).await {
        ServerMessage::Saved { paths, .. } => assert_eq!(paths, vec!["saved.json"]),
        other => panic!("expected saved, got {other:?}"),
    }
    let loaded = motif_detect::DetectionResult::read(&s.root.join("RESULT.json")).unwrap();
    let saved = motif_detect::DetectionResult::read(&s.root.join("saved.json")).unwrap();
    assert_eq!(serde_json::to_value(&saved).unwrap(), serde_json::to_value(&loaded).unwrap());
    send(&mut ws, json!({"type": "save_detections", "path": "saved.ply"})).await;
    expect_error(next_text(&mut ws).await, "name it .json");
    send(&mut ws, json!({"type": "save_detections", "path": "RESULT.json", "overwrite": true})).await;
    assert!(matches!(next_text(&mut ws).await, ServerMessage::Error { .. }));
    assert!(!s.root.join("saved.ply").exists());
    send(&mut ws, json!({"type": "load_detections", "path": "broken.json"})).await;
    assert!(matches!(next_text(&mut ws).await, ServerMessage::Error { .. }));
    // The detector itself, cancelled: a cancel reply (or the result, if it was quicker).
    send(&mut ws, json!({"type": "detect"})).await;
    send(&mut ws, json!({"type": "cancel"})).await;
    match next_text(&mut ws).await {
        ServerMessage::Cancelled { job } => assert_eq!(job, "detect"),
        ServerMessage::Detections { point_class, .. } => {
            assert_eq!(point_class.len(), ex.mesh.num_vertices())
        }
        other => panic!("expected cancelled or detections, got {other:?}"),
    }
}

#[test]
fn bind_refuses_a_missing_root_and_a_model_outside_it() {
    let rt = tokio::runtime::Builder::new_current_thread().enable_all().build().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let missing = StudioOptions { root: dir.path().join("nope"), ..Default::default() };
    assert!(rt.block_on(Studio::bind(missing)).is_err());
    let outside = StudioOptions {
        root: dir.path().to_path_buf(),
        model: Some("../x.obj".into()),
        ..Default::default()
    };
    assert!(rt.block_on(Studio::bind(outside)).is_err());
    let _ = Path::new(".");
}

fn max_difference(a: &[f32], b: &[f32]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y).abs() as f64).fold(0.0, f64::max)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn handles_added_after_a_drag_keep_the_deformation() {
    let s = start().await;
    let mut ws = connect(&s.url).await;
    let n = open_example(&mut ws, "fan").await;
    let hub = json!({"balls": [{"center": [0.0, 0.0, 0.0], "radius": 0.06}]});
    let tip = json!({"balls": [{"center": [0.3, 0.0, 0.0], "radius": 0.04}]});
    let mid = json!({"balls": [{"center": [0.2, 0.0, 0.0], "radius": 0.03}]});
    send(&mut ws, json!({"type": "set_handles", "handles": [hub, tip]})).await;
    let (_, rest) = handles_reply(&mut ws, 2).await;
    let lift = 0.05;
    let moved = translation([0.0, 0.0, lift]);
    send(&mut ws, json!({"type": "drag", "seq": 1, "transforms": [translation([0.0; 3]), moved]})).await;
    let dragged = next_frame(&mut ws, 1).await;
    assert_eq!(dragged.len(), 3 * n);
    assert!(max_difference(&dragged, &rest) > 0.9 * lift, "the drag moved the blade");
    // A third handle on the bent blade, no targets given: the earlier handles keep theirs, the
    // new one holds the blade where it is now, and the shape stays (the snap-back bug pulled
    // the new handle's part back to rest).
    send(&mut ws, json!({"type": "set_handles", "handles": [hub, tip, mid]})).await;
    let (targets, kept) = handles_reply(&mut ws, 3).await;
    assert_eq!(targets[0], translation([0.0; 3]));
    assert_eq!(targets[1], moved);
    assert!(
        targets[2][2][3] > 0.3 * lift,
        "the new handle's target follows the bent blade: {:?}",
        targets[2]
    );
    let drift = max_difference(&kept, &dragged);
    // What the snap-back bug did: the new handle pinned at its rest position.
    let identity = translation([0.0; 3]);
    send(
        &mut ws,
        json!({"type": "set_handles", "handles": [hub, tip, mid], "transforms": [identity, moved, identity]}),
    )
    .await;
    let (_, snapped) = handles_reply(&mut ws, 3).await;
    let snap = max_difference(&snapped, &dragged);
    assert!(
        drift < 0.25 * lift && drift < 0.3 * snap,
        "adding a handle changed the shape by {drift} (lift {lift}; pinning it at rest changes it by {snap})"
    );
    // Targets given by the client (undo to the rest pose) are used as given.
    send(&mut ws, json!({"type": "set_handles", "handles": [hub, tip], "transforms": [identity, identity]}))
        .await;
    let (targets, back) = handles_reply(&mut ws, 2).await;
    assert_eq!(targets, vec![identity; 2]);
    assert!(max_difference(&back, &rest) < 1e-6, "undo to rest: {}", max_difference(&back, &rest));
    // Too many targets for the handles: an error.
    send(&mut ws, json!({"type": "set_handles", "handles": [hub], "transforms": [identity, identity]})).await;
    expect_error(next_text(&mut ws).await, "2 transforms for 1 handles");
}

/// A deformed model exported with its annotation opens with it again: the regions are named by
/// vertex, since the windmill's blade boxes no longer hold the bent blades (the export used to
/// reopen without its annotation). An STL, which keeps no vertex order, goes without it and says
/// so.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_deformed_export_reopens_with_its_annotation() {
    let s = start().await;
    let mut ws = connect(&s.url).await;
    open_example(&mut ws, "windmill").await;
    // The tower's foot (y = 0) held, the top blade's tip (y ≈ 14) pushed back by 1.5.
    let foot = json!({"balls": [{"center": [0.0, 0.0, 0.0], "radius": 1.5}]});
    let tip = json!({"balls": [{"center": [0.0, 14.0, 2.0], "radius": 1.0}]});
    send(&mut ws, json!({"type": "set_handles", "handles": [foot, tip]})).await;
    handles_reply(&mut ws, 2).await;
    let push = translation([0.0, 0.0, -1.5]);
    send(&mut ws, json!({"type": "drag", "seq": 1, "transforms": [translation([0.0; 3]), push]})).await;
    next_frame(&mut ws, 1).await;
    send(&mut ws, json!({"type": "export", "path": "bent.obj"})).await;
    match next_text(&mut ws).await {
        ServerMessage::Saved { paths, notes } => {
            assert_eq!(paths, vec!["bent.obj", "bent.sym.json"]);
            assert!(notes.is_empty(), "{notes:?}");
        }
        other => panic!("expected saved, got {other:?}"),
    }
    send(&mut ws, json!({"type": "export", "path": "bent.stl"})).await;
    match next_text(&mut ws).await {
        ServerMessage::Saved { paths, notes } => {
            assert_eq!(paths, vec!["bent.stl"]);
            assert!(notes.iter().any(|n| n.contains("not written beside a deformed STL")), "{notes:?}");
        }
        other => panic!("expected saved, got {other:?}"),
    }
    send(&mut ws, json!({"type": "open", "path": "bent.obj"})).await;
    match next_text(&mut ws).await {
        ServerMessage::Model { annotation, warnings, .. } => {
            assert!(annotation.is_some(), "the export opens with its annotation: {warnings:?}");
        }
        other => panic!("expected the model, got {other:?}"),
    }
    // The rest shape's annotation itself does not fit the bent windmill: what the pinning is for.
    let bent = motif_core::io::read(&s.root.join("bent.obj")).unwrap().mesh();
    let rest = motif_core::procedural::generate("windmill", 0).unwrap().structure.symmetry;
    assert!(
        motif_deform::resolve_annotation(&bent, &rest).is_err(),
        "the drag should move a blade out of its box"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn building_the_deformation_session_can_be_cancelled() {
    let s = start().await;
    let mut ws = connect(&s.url).await;
    // 100k vertices: building its session takes seconds, the cancel arrives within milliseconds
    // and stops it at the next stage.
    open_example(&mut ws, "windmill_100k").await;
    send(
        &mut ws,
        json!({"type": "set_handles", "handles": [{"balls": [{"center": [0.0, 1.0, 0.0], "radius": 0.3}]}]}),
    )
    .await;
    send(&mut ws, json!({"type": "cancel"})).await;
    match next_text(&mut ws).await {
        ServerMessage::Cancelled { job } => assert_eq!(job, "set_handles"),
        other => panic!("expected the session build to be cancelled, got {other:?}"),
    }
    // Nothing was installed: dragging is refused, and the session works for a new model.
    send(&mut ws, json!({"type": "drag", "seq": 1, "transforms": [translation([0.0; 3])]})).await;
    expect_error(next_text(&mut ws).await, "pick handles");
    open_example(&mut ws, "fan").await;
    send(
        &mut ws,
        json!({"type": "set_handles", "handles": [{"balls": [{"center": [0.0, 0.0, 0.0], "radius": 0.06}]}]}),
    )
    .await;
    handles_reply(&mut ws, 1).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sessions_racing_to_one_new_name_get_one_saved_and_the_rest_already_exists() {
    let s = start().await;
    let mut sockets = Vec::new();
    for _ in 0..8 {
        let mut ws = connect(&s.url).await;
        send(&mut ws, json!({"type": "open", "path": "fan.obj"})).await;
        assert!(matches!(next_text(&mut ws).await, ServerMessage::Model { .. }));
        sockets.push(ws);
    }
    for round in 0..4 {
        let name = format!("race{round}.ply");
        for ws in &mut sockets {
            send(ws, json!({"type": "export", "path": name})).await;
        }
        let mut saved = 0;
        for ws in &mut sockets {
            match next_text(ws).await {
                ServerMessage::Saved { .. } => saved += 1,
                ServerMessage::Error { message, .. } => {
                    assert!(message.contains("already exists"), "{message}")
                }
                other => panic!("expected saved or an error, got {other:?}"),
            }
        }
        assert_eq!(saved, 1, "round {round}: {saved} sessions were told their {name} was saved");
    }
    // A FIFO under the root is not written through (that hung the session's thread).
    if cfg!(unix)
        && std::process::Command::new("mkfifo")
            .arg(s.root.join("fifo.obj"))
            .status()
            .is_ok_and(|st| st.success())
    {
        send(&mut sockets[0], json!({"type": "export", "path": "fifo.obj", "overwrite": true})).await;
        expect_error(next_text(&mut sockets[0]).await, "not a regular file");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_export_whose_annotation_is_refused_writes_nothing() {
    let s = start().await;
    let ex = motif_core::procedural::generate("windmill", 1).unwrap();
    motif_core::io::write_mesh(&s.root.join("w.obj"), &ex.mesh).unwrap();
    let annotation = serde_json::to_string(&ex.structure.symmetry).unwrap();
    std::fs::write(s.root.join("w.sym.json"), &annotation).unwrap();
    std::fs::write(s.root.join("other.sym.json"), "{}").unwrap();
    let mut ws = connect(&s.url).await;
    send(&mut ws, json!({"type": "open", "path": "w.obj"})).await;
    assert!(matches!(next_text(&mut ws).await, ServerMessage::Model { .. }));
    // Another format beside the model: the annotation read with it already says the same.
    send(&mut ws, json!({"type": "export", "path": "w.ply"})).await;
    match next_text(&mut ws).await {
        ServerMessage::Saved { paths, .. } => assert_eq!(paths, vec!["w.ply".to_string()]),
        other => panic!("expected saved, got {other:?}"),
    }
    assert_eq!(std::fs::read_to_string(s.root.join("w.sym.json")).unwrap(), annotation, "input kept");
    // The annotation's file exists: refused before the model is written.
    send(&mut ws, json!({"type": "export", "path": "other.obj"})).await;
    expect_error(next_text(&mut ws).await, "already exists");
    assert!(!s.root.join("other.obj").exists(), "no model left behind");
    assert_eq!(std::fs::read_to_string(s.root.join("other.sym.json")).unwrap(), "{}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn exports_can_be_sent_back_for_download() {
    let s = start().await;
    let mut ws = connect(&s.url).await;
    let n = open_example(&mut ws, "fan").await;
    send(&mut ws, json!({"type": "export", "path": "fan-out.ply", "download": true})).await;
    match next_text(&mut ws).await {
        ServerMessage::Saved { paths, .. } => assert_eq!(paths[0], "fan-out.ply"),
        other => panic!("expected saved, got {other:?}"),
    }
    let file = match next(&mut ws).await {
        Reply::Binary(b) => b,
        _ => panic!("expected the file"),
    };
    assert_eq!(u32::from_le_bytes(file[0..4].try_into().unwrap()), 4);
    let name_len = u32::from_le_bytes(file[8..12].try_into().unwrap()) as usize;
    let len = u32::from_le_bytes(file[12..16].try_into().unwrap()) as usize;
    let name = &file[FRAME_HEADER_BYTES..FRAME_HEADER_BYTES + name_len];
    assert_eq!(name, b"fan-out.ply");
    let bytes = &file[FRAME_HEADER_BYTES + name_len..];
    assert_eq!(bytes.len(), len);
    assert_eq!(bytes, std::fs::read(s.root.join("fan-out.ply")).unwrap().as_slice());
    let back = motif_core::io::read_from_bytes(bytes, motif_core::io::Format::Ply, Path::new("fan-out.ply"))
        .unwrap();
    assert_eq!(back.vertices.len(), n);
}

/// The raw HTTP response to `request` (sent to the server of `s`, connection closed after it).
async fn http(s: &Server, request: &str) -> String {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let addr = s.url.trim_start_matches("ws://").trim_end_matches("/ws").to_string();
    let mut stream = tokio::net::TcpStream::connect(&addr).await.unwrap();
    let request = request.replace("{host}", &addr);
    stream.write_all(request.as_bytes()).await.unwrap();
    let mut out = Vec::new();
    stream.read_to_end(&mut out).await.unwrap();
    String::from_utf8_lossy(&out).into_owned()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_page_answers_get_and_refuses_other_methods() {
    let s = start().await;
    let get = http(&s, "GET / HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n\r\n").await;
    assert!(get.starts_with("HTTP/1.1 200"), "{get}");
    for method in ["POST", "PUT", "DELETE"] {
        let r = http(
            &s,
            &format!(
                "{method} / HTTP/1.1\r\nHost: {{host}}\r\nContent-Length: 0\r\nConnection: close\r\n\r\n"
            ),
        )
        .await;
        assert!(r.starts_with("HTTP/1.1 405"), "{method}: {r}");
        assert!(r.to_ascii_lowercase().contains("allow: get, head"), "{method}: {r}");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_annotation_that_does_not_fit_is_refused_and_an_identical_one_beside_an_export_is_kept() {
    let s = start().await;
    let windmill = motif_core::procedural::generate("windmill", 1).unwrap();
    std::fs::write(s.root.join("w.sym.json"), serde_json::to_string(&windmill.structure.symmetry).unwrap())
        .unwrap();
    let fence = motif_core::procedural::generate("fence", 1).unwrap();
    motif_core::io::write_mesh(&s.root.join("f.obj"), &fence.mesh).unwrap();
    // A stale annotation beside the model (here the windmill's) is not loaded with it: the
    // model opens without it and says why.
    std::fs::copy(s.root.join("w.sym.json"), s.root.join("f.sym.json")).unwrap();
    let mut ws = connect(&s.url).await;
    send(&mut ws, json!({"type": "open", "path": "f.obj"})).await;
    match next_text(&mut ws).await {
        ServerMessage::Model { annotation, warnings, .. } => {
            assert!(annotation.is_none());
            assert!(
                warnings.iter().any(|w| w.contains("f.sym.json was not loaded: it does not fit this model")),
                "{warnings:?}"
            );
        }
        other => panic!("expected the model, got {other:?}"),
    }
    // An annotation beside the model that cannot be read does not stop the model opening.
    std::fs::write(s.root.join("f.sym.json"), "{ not json").unwrap();
    send(&mut ws, json!({"type": "open", "path": "f.obj"})).await;
    match next_text(&mut ws).await {
        ServerMessage::Model { annotation, warnings, .. } => {
            assert!(annotation.is_none());
            assert!(warnings.iter().any(|w| w.contains("f.sym.json was not loaded")), "{warnings:?}");
        }
        other => panic!("expected the model, got {other:?}"),
    }
    // The windmill's annotation on the fence: its regions select nothing there. It used to be
    // accepted ("6 symmetries") and fail at the first click.
    send(&mut ws, json!({"type": "load_annotation", "path": "w.sym.json"})).await;
    expect_error(next_text(&mut ws).await, "does not fit the open model");
    // The fence's own symmetries, exported beside the model in two formats: the second export
    // finds the same annotation beside it and keeps it.
    send(&mut ws, json!({"type": "detect_symmetry"})).await;
    match next_text(&mut ws).await {
        ServerMessage::Annotation { ok, .. } => assert!(ok),
        other => panic!("expected the annotation, got {other:?}"),
    }
    send(&mut ws, json!({"type": "export", "path": "out.ply"})).await;
    match next_text(&mut ws).await {
        ServerMessage::Saved { paths, .. } => assert_eq!(paths, vec!["out.ply", "out.sym.json"]),
        other => panic!("expected saved, got {other:?}"),
    }
    let side = std::fs::read(s.root.join("out.sym.json")).unwrap();
    send(&mut ws, json!({"type": "export", "path": "out.glb"})).await;
    match next_text(&mut ws).await {
        ServerMessage::Saved { paths, .. } => assert_eq!(paths, vec!["out.glb"]),
        other => panic!("expected saved, got {other:?}"),
    }
    assert_eq!(std::fs::read(s.root.join("out.sym.json")).unwrap(), side);
    // An annotation is JSON: a model's extension is refused.
    send(&mut ws, json!({"type": "save_annotation", "path": "f2.obj"})).await;
    expect_error(next_text(&mut ws).await, "name it .json");
    assert!(!s.root.join("f2.obj").exists());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_files_under_the_root_are_listed_for_the_path_fields() {
    let s = start().await;
    let shelf = motif_core::procedural::generate("shelf", 1).unwrap();
    std::fs::create_dir_all(s.root.join("scans/deep/er/still")).unwrap();
    std::fs::create_dir_all(s.root.join(".hidden")).unwrap();
    motif_core::io::write_mesh(&s.root.join("shelf.obj"), &shelf.mesh).unwrap();
    motif_core::io::write_mesh(&s.root.join("scans/a.PLY"), &shelf.mesh).unwrap();
    motif_core::io::write_mesh(&s.root.join(".hidden/b.obj"), &shelf.mesh).unwrap();
    motif_core::io::write_mesh(&s.root.join("scans/deep/er/still/c.obj"), &shelf.mesh).unwrap();
    std::fs::write(s.root.join("shelf.sym.json"), "{}").unwrap();
    std::fs::write(s.root.join("notes.txt"), "not listed").unwrap();
    // Links: one to a file under the root is listed, one leading outside is not.
    #[cfg(unix)]
    {
        std::os::unix::fs::symlink(s.root.join("shelf.obj"), s.root.join("shelf-link.obj")).unwrap();
        std::os::unix::fs::symlink(s.root.join("../outside.obj"), s.root.join("outside-link.obj")).unwrap();
    }
    let mut ws = connect(&s.url).await;
    send(&mut ws, json!({"type": "list_files"})).await;
    match next_text(&mut ws).await {
        ServerMessage::Files { models, json, truncated } => {
            // Hidden folders are skipped and the listing stops four folders deep.
            // (`start` writes fan.obj; the others are this test's.)
            let mut want = vec!["fan.obj", "scans/a.PLY", "shelf.obj"];
            if cfg!(unix) {
                want.insert(2, "shelf-link.obj");
            }
            assert_eq!(models, want);
            assert_eq!(json, vec!["shelf.sym.json"]);
            assert!(truncated);
        }
        other => panic!("expected the files, got {other:?}"),
    }
}
