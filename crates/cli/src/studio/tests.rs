//! Server tests: the HTTP and WebSocket surface on a real socket.

use std::time::Duration;

use futures_util::{SinkExt, StreamExt};
use serde_json::{Value, json};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio_tungstenite::tungstenite::Message as WsMessage;

use super::*;

type Client = tokio_tungstenite::WebSocketStream<tokio_tungstenite::MaybeTlsStream<tokio::net::TcpStream>>;

fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_multi_thread().worker_threads(2).enable_all().build().unwrap()
}

/// A studio on a free loopback port; returns its address.
async fn start(max_sessions: usize) -> (SocketAddr, tempfile::TempDir) {
    let (addr, out, _) = start_shared(max_sessions).await;
    (addr, out)
}

/// A studio on a free loopback port; returns its address and its shared state.
async fn start_shared(max_sessions: usize) -> (SocketAddr, tempfile::TempDir, Arc<Shared>) {
    let out = tempfile::tempdir().unwrap();
    let options = Options {
        bind: IpAddr::from([127, 0, 0, 1]),
        port: 0,
        open: false,
        out: out.path().to_path_buf(),
        max_sessions,
        allow_hosts: vec!["Studio.Example:7878".into()],
    };
    let shared = Arc::new(Shared {
        controls: controls::Catalogue::build(),
        hosts: options.hosts(),
        options,
        sessions: Mutex::new(HashMap::new()),
        counter: AtomicU64::new(0),
        key: std::hash::RandomState::new(),
    });
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    let served = shared.clone();
    tokio::spawn(async move { axum::serve(listener, router(served)).await });
    (addr, out, shared)
}

/// Upload `bytes` as `name` to session `id`; the status code.
async fn upload_file(addr: SocketAddr, id: &str, name: &str, bytes: &[u8]) -> u16 {
    let head = format!(
        "POST /api/session/{id}/upload/{name} HTTP/1.1\r\nHost: {addr}\r\nContent-Length: {}\r\nConnection: close\r\n\r\n",
        bytes.len()
    );
    raw(addr, &head, bytes).await.0
}

/// Send raw HTTP/1.1 bytes (so paths are not normalised) and return the status code
/// and body.
async fn raw(addr: SocketAddr, head: &str, body: &[u8]) -> (u16, String) {
    let mut s = tokio::net::TcpStream::connect(addr).await.unwrap();
    s.write_all(head.as_bytes()).await.unwrap();
    // A server may answer (413) before the whole body is sent; ignore write errors.
    let _ = s.write_all(body).await;
    let mut buf = Vec::new();
    let _ = tokio::time::timeout(Duration::from_secs(20), s.read_to_end(&mut buf)).await;
    let text = String::from_utf8_lossy(&buf).to_string();
    let code = text.split(' ').nth(1).and_then(|c| c.parse().ok()).unwrap_or(0);
    (code, text)
}

async fn get(addr: SocketAddr, path: &str) -> (u16, String) {
    raw(addr, &format!("GET {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n"), &[]).await
}

async fn connect(addr: SocketAddr) -> (Client, String) {
    let (mut ws, _) = tokio_tungstenite::connect_async(format!("ws://{addr}/ws")).await.unwrap();
    let hello = next_json(&mut ws, "hello").await;
    (ws, hello["session"].as_str().unwrap().to_string())
}

/// The first message `pick` takes (skipping the others) within 60 s; `what` names it
/// in the failure.
async fn next_where<T>(ws: &mut Client, what: &str, pick: impl Fn(WsMessage) -> Option<T>) -> T {
    let deadline = tokio::time::Instant::now() + Duration::from_secs(60);
    loop {
        let m = tokio::time::timeout_at(deadline, ws.next())
            .await
            .unwrap_or_else(|_| panic!("no {what} within 60 s"))
            .expect("socket open")
            .expect("no socket error");
        if let Some(v) = pick(m) {
            return v;
        }
    }
}

/// The next JSON message of `kind`, skipping others (frames, notices); 60 s at most.
async fn next_json(ws: &mut Client, kind: &str) -> Value {
    next_where(ws, &format!("`{kind}` message"), |m| match m {
        WsMessage::Text(t) => Some(serde_json::from_str::<Value>(&t).unwrap()).filter(|v| v["type"] == kind),
        _ => None,
    })
    .await
}

async fn send(ws: &mut Client, v: Value) {
    ws.send(WsMessage::Text(v.to_string().into())).await.unwrap();
}

async fn live(addr: SocketAddr) -> u64 {
    let (code, text) = get(addr, "/api/sessions").await;
    assert_eq!(code, 200, "{text}");
    let body = &text[text.find("\r\n\r\n").unwrap() + 4..];
    serde_json::from_str::<Value>(body).unwrap()["live"].as_u64().unwrap()
}

#[test]
fn static_files_only_from_the_embedded_set() {
    runtime().block_on(async {
        let (addr, _out) = start(4).await;
        let (code, page) = get(addr, "/").await;
        assert_eq!(code, 200);
        assert!(page.contains("phenomena studio"));
        assert_eq!(get(addr, "/static/app.js").await.0, 200);
        for path in [
            "/static/../Cargo.toml",
            "/../../Cargo.toml",
            "/static/%2e%2e/%2e%2e/Cargo.toml",
            "/static/..%2fmod.rs",
            "/etc/passwd",
            "/static/web/app.js",
        ] {
            let (code, text) = get(addr, path).await;
            assert_eq!(code, 404, "{path}: {text}");
            assert!(!text.contains("[package]"), "{path} leaked a file");
        }
    });
}

#[test]
fn oversized_uploads_get_413_and_small_ones_land() {
    runtime().block_on(async {
        let (addr, _out) = start(4).await;
        let (_ws, id) = connect(addr).await;
        let big = vec![b'x'; MAX_UPLOAD_BYTES + 1];
        let head = format!(
            "POST /api/session/{id}/upload/big.obj HTTP/1.1\r\nHost: {addr}\r\nContent-Length: {}\r\nConnection: close\r\n\r\n",
            big.len()
        );
        let (code, text) = raw(addr, &head, &big).await;
        assert_eq!(code, 413, "{}", &text[..text.len().min(300)]);
        let small = b"v 0 0 0\nv 1 0 0\nv 0 0 1\nf 1 2 3\n";
        let head = format!(
            "POST /api/session/{id}/upload/tri.obj HTTP/1.1\r\nHost: {addr}\r\nContent-Length: {}\r\nConnection: close\r\n\r\n",
            small.len()
        );
        let (code, text) = raw(addr, &head, small).await;
        assert_eq!(code, 200, "{text}");
        let head = format!(
            "POST /api/session/{id}/upload/..%2fx.obj HTTP/1.1\r\nHost: {addr}\r\nContent-Length: {}\r\nConnection: close\r\n\r\n",
            small.len()
        );
        assert_eq!(raw(addr, &head, small).await.0, 400, "names with a path are refused");
        for (name, code) in [("a%20b.v2.obj", 200), (".hidden", 400), ("%2Fetc%2Fx", 400), ("a%00b", 400)] {
            assert_eq!(upload_file(addr, &id, name, small).await, code, "{name}");
        }
    });
}

#[test]
fn tabs_have_their_own_scenes_and_bad_messages_keep_the_connection() {
    runtime().block_on(async {
        let (addr, _out) = start(4).await;
        let (mut a, _) = connect(addr).await;
        let (mut b, _) = connect(addr).await;
        send(&mut a, json!({"type": "builtin", "name": "flame-paper"})).await;
        let sa = next_json(&mut a, "scene").await;
        send(&mut b, json!({"type": "builtin", "name": "sparkle-paper"})).await;
        let sb = next_json(&mut b, "scene").await;
        assert_eq!((sa["phenomenon"].as_str(), sb["phenomenon"].as_str()), (Some("flame"), Some("sparkle")));
        send(&mut a, json!({"type": "set", "path": "scene.seed", "value": 77})).await;
        let sa = next_json(&mut a, "scene").await;
        assert_eq!(sa["scene"]["scene"]["seed"], 77);
        send(&mut b, json!({"type": "save"})).await;
        let saved = next_json(&mut b, "saved").await;
        assert!(saved["toml"].as_str().unwrap().contains("[sparkle"), "{saved}");
        assert!(!saved["toml"].as_str().unwrap().contains("seed = 77"), "tab b saw tab a's change");
        // Malformed and unknown messages get an error; the socket stays usable.
        a.send(WsMessage::Text("{not json".into())).await.unwrap();
        let e = next_json(&mut a, "error").await;
        assert!(e["message"].as_str().unwrap().contains("malformed"), "{e}");
        send(&mut a, json!({"type": "explode"})).await;
        next_json(&mut a, "error").await;
        send(&mut a, json!({"type": "set", "path": "flame.emitter.rate_per_s", "value": -5})).await;
        let e = next_json(&mut a, "error").await;
        assert!(e["issues"][0]["field"].as_str().unwrap().ends_with("rate_per_s"), "{e}");
        send(&mut a, json!({"type": "save"})).await;
        let saved = next_json(&mut a, "saved").await;
        assert!(saved["toml"].as_str().unwrap().contains("seed = 77"), "{saved}");
        assert!(!saved["toml"].as_str().unwrap().contains("rate_per_s = -5"), "a refused value stays out");
    });
}

#[test]
fn closing_a_tab_stops_its_simulation_and_the_cap_holds() {
    runtime().block_on(async {
        let (addr, _out) = start(2).await;
        let (mut a, _) = connect(addr).await;
        send(&mut a, json!({"type": "builtin", "name": "flame-paper"})).await;
        next_json(&mut a, "frame").await;
        let (b, _) = connect(addr).await;
        assert_eq!(live(addr).await, 2);
        // A third tab is refused while two are open.
        let third = tokio_tungstenite::connect_async(format!("ws://{addr}/ws")).await;
        assert!(third.is_err(), "a third session was accepted past the cap of 2");
        drop(b);
        a.close(None).await.unwrap();
        drop(a);
        let deadline = tokio::time::Instant::now() + Duration::from_secs(10);
        while live(addr).await > 0 {
            assert!(
                tokio::time::Instant::now() < deadline,
                "sessions still live 10 s after their tabs closed"
            );
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
    });
}

#[test]
fn other_sites_cannot_open_a_session() {
    runtime().block_on(async {
        let (addr, _out) = start(4).await;
        let handshake = |origin: &str| {
            format!(
                "GET /ws HTTP/1.1\r\nHost: {addr}\r\nConnection: Upgrade\r\nUpgrade: websocket\r\n\
                 Sec-WebSocket-Version: 13\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nOrigin: {origin}\r\n\r\n"
            )
        };
        let status = |origin: String| async move {
            let mut s = tokio::net::TcpStream::connect(addr).await.unwrap();
            s.write_all(handshake(&origin).as_bytes()).await.unwrap();
            let mut buf = [0u8; 12];
            s.read_exact(&mut buf).await.unwrap();
            buf
        };
        assert_eq!(&status("http://evil.example".into()).await, b"HTTP/1.1 403");
        let buf = status(format!("http://{addr}")).await;
        assert_eq!(&buf, b"HTTP/1.1 101", "the page's own origin is accepted");
    });
}

#[test]
fn snow_glb_download_is_a_gltf_binary() {
    runtime().block_on(async {
        let (addr, _out) = start(4).await;
        let (mut ws, id) = connect(addr).await;
        assert_eq!(get(addr, &format!("/api/session/{id}/snow.glb")).await.0, 409, "no snow scene yet");
        send(&mut ws, json!({"type": "builtin", "name": "snow-table"})).await;
        next_json(&mut ws, "frame").await;
        let mut s = tokio::net::TcpStream::connect(addr).await.unwrap();
        s.write_all(
            format!("GET /api/session/{id}/snow.glb HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n")
                .as_bytes(),
        )
        .await
        .unwrap();
        let mut buf = Vec::new();
        s.read_to_end(&mut buf).await.unwrap();
        let split = buf.windows(4).position(|w| w == b"\r\n\r\n").unwrap() + 4;
        let head = String::from_utf8_lossy(&buf[..split]);
        assert!(head.starts_with("HTTP/1.1 200"), "{head}");
        assert!(head.contains("model/gltf-binary"), "{head}");
        assert_eq!(&buf[split..split + 4], b"glTF", "GLB magic");
    });
}

/// A glTF (one triangle) whose only buffer has the URI `uri`.
fn gltf_with_buffer(uri: &str) -> String {
    format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}}}}]}}],"accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","max":[4,0,4],"min":[0,0,0]}}],"bufferViews":[{{"buffer":0,"byteLength":36}}],"buffers":[{{"uri":{uri:?},"byteLength":36}}]}}"#
    )
}

/// A page cannot make the studio read any file but its own uploads. Every
/// hostile glTF buffer URI is refused with a message naming the scene key and the URI
/// (never the server's folders), without reading it; the session and other sessions
/// keep working.
#[test]
fn hostile_gltf_buffer_uris_are_refused_without_reading() {
    runtime().block_on(async {
        let (addr, _out, shared) = start_shared(4).await;
        let (mut ws, id) = connect(addr).await;
        let (mut other, _) = connect(addr).await;
        let dir = shared.sessions().get(&id).unwrap().dir.clone();
        let folder = dir.to_string_lossy().into_owned();
        // What a page cannot upload but another program might have put there: a FIFO
        // (reading it would block the session for ever) and a symlink out of the folder.
        #[cfg(unix)]
        {
            let made = std::process::Command::new("mkfifo").arg(dir.join("pipe.bin")).status();
            assert!(made.unwrap().success());
            std::os::unix::fs::symlink("/etc/hostname", dir.join("link.bin")).unwrap();
        }
        let triangle: Vec<u8> =
            [[0.0f32, 0.0, 0.0], [0.0, 0.0, 4.0], [4.0, 0.0, 0.0]].iter().flatten().flat_map(|v| v.to_le_bytes()).collect();
        assert_eq!(upload_file(addr, &id, "tri.bin", &triangle).await, 200);
        let mut cases = vec![
            ("/etc/hostname", "absolute paths are refused"),
            ("/dev/zero", "absolute paths are refused"),
            ("../../../../etc/hostname", "plain name"),
            ("sub/tri.bin", "plain name"),
            ("%2E%2E%2Ftri.bin", "plain name"),
            ("file:///etc/hostname", "only relative paths and data: URIs"),
        ];
        if cfg!(unix) {
            cases.push(("pipe.bin", "not a regular file"));
            cases.push(("link.bin", "symlink"));
        }
        for (uri, why) in cases {
            assert_eq!(upload_file(addr, &id, "m.gltf", gltf_with_buffer(uri).as_bytes()).await, 200);
            let text = "[scene]\nframes = 5\n[geometry]\nmesh = \"m.gltf\"\n[snow]\nmap_resolution = 16\ndirections = 4\nshadow_resolution = 32\n";
            send(&mut ws, json!({"type": "toml", "text": text, "name": "hostile.toml"})).await;
            let e = tokio::time::timeout(Duration::from_secs(20), next_json(&mut ws, "error"))
                .await
                .unwrap_or_else(|_| panic!("{uri}: no answer in 20 s (a blocked read?)"));
            let message = e["message"].as_str().unwrap();
            assert!(message.contains(&format!("geometry.mesh = \"m.gltf\": its glTF buffer {uri:?}")), "{message}");
            assert!(message.contains(why), "{uri}: {message}");
            assert!(!message.contains(&folder), "{uri}: the message reveals the session folder: {message}");
            assert_eq!(e["issues"][0]["field"], "geometry.mesh", "{e}");
        }
        // A good buffer beside the glTF works in the same session; another tab never
        // stopped.
        assert_eq!(upload_file(addr, &id, "m.gltf", gltf_with_buffer("tri.bin").as_bytes()).await, 200);
        let text = "[scene]\nframes = 5\n[geometry]\nmesh = \"m.gltf\"\n[snow]\nmap_resolution = 16\ndirections = 4\nshadow_resolution = 32\n";
        send(&mut ws, json!({"type": "toml", "text": text})).await;
        next_json(&mut ws, "frame").await;
        send(&mut other, json!({"type": "builtin", "name": "flame-paper"})).await;
        next_json(&mut other, "frame").await;
    });
}

/// Scene keys that name files take only plain uploaded names in the studio.
#[test]
fn scene_files_are_read_only_from_the_session_uploads() {
    runtime().block_on(async {
        let (addr, _out) = start(4).await;
        let (mut ws, _) = connect(addr).await;
        send(&mut ws, json!({"type": "builtin", "name": "flame-paper"})).await;
        next_json(&mut ws, "frame").await;
        for path in ["../bg.png", "/etc/passwd", "a/bg.png", "missing.png"] {
            send(
                &mut ws,
                json!({"type": "set", "path": "render.background", "value": {"kind": "image", "path": path}}),
            )
            .await;
            let e = next_json(&mut ws, "error").await;
            let message = e["message"].as_str().unwrap();
            assert!(message.contains(&format!("render.background.path = {path:?}")), "{message}");
            let why = if path == "missing.png" { "no such file" } else { "plain name" };
            assert!(message.contains(why), "{message}");
        }
    });
}

/// A page of another site whose name was rebound to 127.0.0.1 names its own
/// host: refused on every route, with a message saying how to allow a name. The
/// loopback names, the bind address and `--allow-host` names are served.
#[test]
fn only_the_hosts_the_studio_is_served_as_are_answered() {
    runtime().block_on(async {
        let (addr, _out) = start(4).await;
        let port = addr.port();
        let request = |host: &str, path: &str| {
            format!("GET {path} HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n\r\n")
        };
        for host in [format!("evil.example:{port}"), "evil.example".into(), format!("127.0.0.2:{port}")] {
            for path in ["/", "/static/app.js", "/api/sessions", "/api/controls", "/api/session/x/snow.glb"] {
                let (code, text) = raw(addr, &request(&host, path), &[]).await;
                assert_eq!(code, 403, "{host} {path}: {text}");
                assert!(text.contains("--allow-host"), "{text}");
            }
        }
        // The WebSocket handshake of a rebound page: its Origin matches its Host.
        let handshake = format!(
            "GET /ws HTTP/1.1\r\nHost: evil.example:{port}\r\nConnection: Upgrade\r\nUpgrade: websocket\r\n\
             Sec-WebSocket-Version: 13\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nOrigin: http://evil.example:{port}\r\n\r\n"
        );
        assert_eq!(raw(addr, &handshake, &[]).await.0, 403);
        let (code, _) = raw(addr, "GET / HTTP/1.0\r\n\r\n", &[]).await;
        assert_eq!(code, 400, "no Host at all");
        for host in [format!("127.0.0.1:{port}"), format!("localhost:{port}"), format!("LOCALHOST:{port}"), format!("[::1]:{port}"), format!("studio.example:{port}")] {
            assert_eq!(raw(addr, &request(&host, "/"), &[]).await.0, 200, "{host}");
        }
        assert_eq!(super::host_name("[::1]:80"), "::1");
        assert_eq!(super::host_name("Example.COM"), "example.com");
    });
}

/// A session that fails tells its page why and stays usable; the sequence
/// that used to panic (keyframes set behind the editor's back, then a stroke on the
/// new keyframe) is an ordinary edit now.
#[test]
fn a_failing_session_says_why_and_goes_on() {
    runtime().block_on(async {
        let (addr, _out) = start(4).await;
        let (mut ws, _) = connect(addr).await;
        let (mut other, _) = connect(addr).await;
        send(&mut ws, json!({"type": "builtin", "name": "aurora-scene1"})).await;
        let scene = next_json(&mut ws, "scene").await;
        let mut keyframes = scene["scene"]["aurora"]["keyframes"].as_array().unwrap().clone();
        let mut added = keyframes.last().unwrap().clone();
        added["frame"] = json!(added["frame"].as_u64().unwrap() + 100);
        keyframes.push(added);
        send(&mut ws, json!({"type": "set", "path": "aurora.keyframes", "value": keyframes})).await;
        next_json(&mut ws, "scene").await;
        let stroke: Vec<[f32; 2]> = (0..10).map(|i| [60.0 + 20.0 * i as f32, 390.0]).collect();
        send(&mut ws, json!({"type": "aurora", "op": "stroke", "keyframe": 2, "points": stroke})).await;
        let answer = next_json(&mut ws, "refused").await;
        assert!(
            answer["message"].as_str().unwrap().contains("every sheet of keyframe 2 is drawn"),
            "{answer}"
        );
        // A bug inside the session thread: the page is told, the session goes on.
        send(&mut ws, json!({"type": "panic"})).await;
        let e = next_json(&mut ws, "error").await;
        assert!(e["message"].as_str().unwrap().contains("internal error"), "{e}");
        send(&mut ws, json!({"type": "builtin", "name": "flame-paper"})).await;
        next_json(&mut ws, "frame").await;
        send(&mut other, json!({"type": "builtin", "name": "sparkle-paper"})).await;
        next_json(&mut other, "frame").await;
    });
}

/// "render final" writes every format the phenomenon has (here VDB volumes with
/// their manifests), and refuses one it has not, naming those it has.
#[test]
fn render_final_writes_the_chosen_format() {
    runtime().block_on(async {
        let (addr, _out) = start(4).await;
        let (mut ws, _) = connect(addr).await;
        send(&mut ws, json!({"type": "builtin", "name": "snow-table"})).await;
        next_json(&mut ws, "scene").await;
        send(&mut ws, json!({"type": "render_final", "frames": 1, "format": "vdb"})).await;
        let e = next_json(&mut ws, "error").await;
        assert!(
            e["message"].as_str().unwrap().contains("snow scenes are not written as vdb: use png, exr"),
            "{e}"
        );
        send(&mut ws, json!({"type": "render_final", "frames": 1, "format": "gif"})).await;
        let e = next_json(&mut ws, "error").await;
        assert!(e["message"].as_str().unwrap().contains("no format `gif`"), "{e}");
        send(&mut ws, json!({"type": "builtin", "name": "flame-paper"})).await;
        next_json(&mut ws, "scene").await;
        send(&mut ws, json!({"type": "render_final", "frames": 2, "format": "vdb"})).await;
        let done = next_json(&mut ws, "rendered").await;
        let dir = std::path::PathBuf::from(done["dir"].as_str().unwrap());
        let mut files: Vec<String> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        files.sort();
        assert_eq!(
            files,
            [
                "frame_00000.vdb",
                "frame_00000.vdb.json",
                "frame_00001.vdb",
                "frame_00001.vdb.json",
                "scene.toml"
            ]
        );
    });
}

/// The next message of `kind` for which `pred` holds, skipping others; 60 s at most.
async fn until_json(ws: &mut Client, kind: &str, pred: impl Fn(&Value) -> bool) -> Value {
    loop {
        let v = next_json(ws, kind).await;
        if pred(&v) {
            return v;
        }
    }
}

/// The next preview image of frame `frame` (its JPEG bytes and generation); 60 s at most.
async fn image_of(ws: &mut Client, frame: u32) -> (u32, Vec<u8>) {
    next_where(ws, &format!("image of frame {frame}"), |m| match m {
        WsMessage::Binary(b) => {
            let word = |i: usize| u32::from_le_bytes(b[4 * i..4 * i + 4].try_into().unwrap());
            (word(1) == frame).then(|| (word(0), b[16..].to_vec()))
        }
        _ => None,
    })
    .await
}

/// The `time` message of the next scene change: how time was kept.
async fn change_of(ws: &mut Client) -> Value {
    let scene = next_json(ws, "scene").await;
    let generation = scene["generation"].clone();
    until_json(ws, "time", |t| t["generation"] == generation && t.get("change").is_some()).await
}

/// The preview is a timeline: seeking shows that frame (the same image as playing to
/// it, from a kept state), a render-only change keeps the frame from the running
/// simulation, a simulation change simulates again up to it, undo and redo restore the
/// values, and play loops at the scene's end or stops there.
#[test]
fn the_preview_keeps_time() {
    runtime().block_on(async {
        let (addr, _out) = start(4).await;
        let (mut ws, _) = connect(addr).await;
        send(&mut ws, json!({"type": "preview", "width": 160, "height": 96})).await;
        send(&mut ws, json!({"type": "builtin", "name": "flame-paper"})).await;
        change_of(&mut ws).await;
        send(&mut ws, json!({"type": "set", "path": "scene.frames", "value": 30})).await;
        let t = change_of(&mut ws).await;
        assert_eq!(t["change"], "render", "the length is not part of the simulation: {t}");
        // Played through frame 12: the image of frame 12 as played.
        let (_, played) = image_of(&mut ws, 12).await;
        until_json(&mut ws, "frame", |f| f["frame"].as_u64() >= Some(20)).await;
        send(&mut ws, json!({"type": "seek", "frame": 12})).await;
        let t = until_json(&mut ws, "time", |t| t["target"].is_null() && t["frame"] == 12).await;
        assert!(t["kept"].as_array().unwrap().iter().any(|k| k == 0), "frame 0's state is kept: {t}");
        assert_eq!(t["playing"], false, "seeking pauses");
        send(&mut ws, json!({"type": "seek", "frame": 12})).await;
        let (_, sought) = image_of(&mut ws, 12).await;
        assert_eq!(sought, played, "frame 12 from a kept state is the frame played");

        // Render-only: the frame and the simulation's state stay.
        send(&mut ws, json!({"type": "set", "path": "scene.exposure_ev", "value": 1.5})).await;
        let t = change_of(&mut ws).await;
        assert_eq!((t["change"].as_str(), t["frame"].as_u64()), (Some("render"), Some(12)), "{t}");
        let (_, brighter) = image_of(&mut ws, 12).await;
        assert_ne!(brighter, played);
        // Simulation: simulated again up to the same frame.
        send(&mut ws, json!({"type": "set", "path": "flame.emitter.rate_per_s", "value": 500.0})).await;
        let t = change_of(&mut ws).await;
        assert_eq!((t["change"].as_str(), t["frame"].as_u64()), (Some("simulation"), Some(12)), "{t}");
        until_json(&mut ws, "time", |t| t["target"].is_null() && t["frame"] == 12).await;

        // Undo, twice, and redo.
        send(&mut ws, json!({"type": "undo"})).await;
        let s = next_json(&mut ws, "scene").await;
        assert_ne!(s["scene"]["flame"]["emitter"]["rate_per_s"], 500.0);
        assert_eq!(s["scene"]["scene"]["exposure_ev"], 1.5);
        send(&mut ws, json!({"type": "undo"})).await;
        let s = next_json(&mut ws, "scene").await;
        assert_eq!(s["scene"]["scene"]["exposure_ev"], 0.0);
        assert_eq!(s["redo"], 2);
        send(&mut ws, json!({"type": "redo"})).await;
        let s = next_json(&mut ws, "scene").await;
        assert_eq!(
            (s["scene"]["scene"]["exposure_ev"].as_f64(), s["dirty"].as_bool()),
            (Some(1.5), Some(true))
        );

        // Loop at the end; with the loop off, stop there.
        send(&mut ws, json!({"type": "seek", "frame": 26})).await;
        until_json(&mut ws, "time", |t| t["target"].is_null() && t["frame"] == 26).await;
        send(&mut ws, json!({"type": "play"})).await;
        until_json(&mut ws, "frame", |f| f["frame"] == 29).await;
        let f = next_json(&mut ws, "frame").await;
        assert_eq!(f["frame"], 0, "after the last frame comes the first: {f}");
        send(&mut ws, json!({"type": "loop", "on": false})).await;
        let t = until_json(&mut ws, "time", |t| t["playing"] == false).await;
        assert_eq!((t["frame"].as_u64(), t["looping"].as_bool()), (Some(29), Some(false)), "{t}");
    });
}

/// Render final takes the frames first..=last (those before are simulated and not
/// written) and says which files it wrote where.
#[test]
fn render_final_writes_exactly_the_frames_asked_for() {
    runtime().block_on(async {
        let (addr, _out) = start(4).await;
        let (mut ws, _) = connect(addr).await;
        send(&mut ws, json!({"type": "builtin", "name": "flame-paper"})).await;
        next_json(&mut ws, "scene").await;
        send(&mut ws, json!({"type": "render_final", "first": 3, "last": 5, "format": "png"})).await;
        let done = next_json(&mut ws, "rendered").await;
        let files = ["frame_00003.png", "frame_00004.png", "frame_00005.png", "scene.toml"];
        assert_eq!(done["files"], json!(files), "{done}");
        assert_eq!((done["first"].as_u64(), done["last"].as_u64()), (Some(3), Some(5)));
        let dir = std::path::PathBuf::from(done["dir"].as_str().unwrap());
        let mut on_disk: Vec<String> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        on_disk.sort();
        assert_eq!(on_disk, files);
        send(&mut ws, json!({"type": "render_final", "first": 5, "last": 2})).await;
        let e = next_json(&mut ws, "error").await;
        assert!(e["message"].as_str().unwrap().contains("last frame 2 is before the first, 5"), "{e}");
    });
}

/// A change that arrives while the simulation is still on its way to a frame keeps
/// that frame (not the progress frame shown on the way), and after a live wind drag
/// nothing of the steered simulation is carried over: undoing the drag simulates the
/// calm scene again.
#[test]
fn changes_keep_the_frame_asked_for_and_steered_states_are_not_reused() {
    runtime().block_on(async {
        let (addr, _out) = start(4).await;
        let (mut ws, _) = connect(addr).await;
        send(&mut ws, json!({"type": "preview", "width": 160, "height": 96})).await;
        send(&mut ws, json!({"type": "builtin", "name": "flame-paper"})).await;
        change_of(&mut ws).await;
        send(&mut ws, json!({"type": "pause"})).await;
        send(&mut ws, json!({"type": "set", "path": "flame.emitter.rate_per_s", "value": 4000.0})).await;
        send(&mut ws, json!({"type": "seek", "frame": 150})).await;
        send(&mut ws, json!({"type": "set", "path": "scene.exposure_ev", "value": 0.5})).await;
        // The last change's time: aimed at 150, then there.
        let t = until_json(&mut ws, "time", |t| t["target"] == 150 && t.get("change").is_some()).await;
        assert_eq!(t["change"], "render", "{t}");
        until_json(&mut ws, "time", |t| t["target"].is_null() && t["frame"] == 150).await;

        send(&mut ws, json!({"type": "wind", "force": [2.0, 0.0, 0.0], "start": true})).await;
        let w = next_json(&mut ws, "wind").await;
        assert_eq!((w["undo"].as_u64(), w["dirty"].as_bool()), (Some(3), Some(true)), "{w}");
        send(&mut ws, json!({"type": "wind", "force": [3.0, 0.0, 0.0]})).await;
        assert_eq!(next_json(&mut ws, "wind").await["undo"], 3, "one drag, one edit");
        send(&mut ws, json!({"type": "wind", "force": [0.0, 0.0, 0.0], "start": true})).await;
        assert_eq!(next_json(&mut ws, "wind").await["undo"], 4, "a new drag, a new edit");
        send(&mut ws, json!({"type": "undo"})).await;
        let t = change_of(&mut ws).await;
        assert_eq!((t["change"].as_str(), t["frame"].as_u64()), (Some("simulation"), Some(150)), "{t}");
        until_json(&mut ws, "time", |t| t["target"].is_null() && t["frame"] == 150).await;
    });
}
