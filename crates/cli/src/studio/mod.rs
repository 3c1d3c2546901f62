//! `phenomena studio`: a local web page that draws aurora shapes, steers every
//! phenomenon and shows it live. Built only with `--features studio`.
//!
//! The browser draws and controls; this side simulates and renders. One WebSocket per
//! browser tab is one session ([`session`]): its own scene, simulation and preview
//! thread. JSON messages go both ways; preview frames come as binary messages (a 16-byte
//! header, then a JPEG). Every scene change bumps the session's generation, and frames of
//! older generations are neither rendered nor shown. The page's files are embedded in the
//! binary and served from that fixed set only.

mod controls;
mod final_render;
mod session;
mod timeline;

use std::collections::HashMap;
use std::hash::BuildHasher;
use std::net::{IpAddr, SocketAddr};
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

use anyhow::{Context, Result};
use axum::Router;
use axum::body::Bytes;
use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::extract::{DefaultBodyLimit, Path as UrlPath, State};
use axum::http::{StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use futures_util::{SinkExt, StreamExt};

pub(crate) use session::Command;

/// Largest upload (a mesh or a background image), bytes.
pub(crate) const MAX_UPLOAD_BYTES: usize = 32 << 20;
/// Largest WebSocket message from the page (a scene or a stroke), bytes.
pub(crate) const MAX_MESSAGE_BYTES: usize = 4 << 20;

/// How the studio is served.
#[derive(Clone, Debug)]
pub(crate) struct Options {
    /// Address to bind (loopback unless told otherwise).
    pub(crate) bind: IpAddr,
    /// Port (0: any free port; the one taken is printed).
    pub(crate) port: u16,
    /// Open the page in the desktop's browser.
    pub(crate) open: bool,
    /// Folder for "render final" outputs.
    pub(crate) out: PathBuf,
    /// Most sessions (browser tabs) at once.
    pub(crate) max_sessions: usize,
    /// Host names accepted besides the loopback names and the bind address.
    pub(crate) allow_hosts: Vec<String>,
}

impl Options {
    /// Every host name a request may name (lowercase, without port or brackets).
    fn hosts(&self) -> Vec<String> {
        let mut hosts: Vec<String> = ["127.0.0.1", "localhost", "::1"].map(String::from).to_vec();
        if !self.bind.is_unspecified() {
            hosts.push(self.bind.to_string());
        }
        hosts.extend(self.allow_hosts.iter().map(|h| host_name(h)));
        hosts
    }
}

/// The host name of a `Host` header value (`name`, `name:port`, `[v6]:port`), lowercase.
fn host_name(value: &str) -> String {
    let name = if let Some(rest) = value.strip_prefix('[') {
        rest.split(']').next().unwrap_or_default()
    } else {
        value
            .rsplit_once(':')
            .map_or(value, |(name, port)| if port.parse::<u16>().is_ok() { name } else { value })
    };
    name.to_ascii_lowercase()
}

/// One live session as the HTTP side sees it.
struct Entry {
    /// Folder of the session's uploads (removed with the session).
    dir: PathBuf,
    /// Commands to its simulation thread.
    commands: std::sync::mpsc::Sender<Command>,
}

/// State shared by every request.
pub(crate) struct Shared {
    options: Options,
    sessions: Mutex<HashMap<String, Entry>>,
    counter: AtomicU64,
    key: std::hash::RandomState,
    controls: controls::Catalogue,
    /// Host names requests may name ([`Options::hosts`]).
    hosts: Vec<String>,
}

impl Shared {
    fn sessions(&self) -> std::sync::MutexGuard<'_, HashMap<String, Entry>> {
        // A panic while holding the lock cannot leave the map half-updated (every
        // update is one insert or remove), so a poisoned lock is still usable.
        self.sessions.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
    }
}

/// The page's files, embedded: (URL path, content type, bytes).
const ASSETS: &[(&str, &str, &str)] = &[
    ("/", "text/html; charset=utf-8", include_str!("web/index.html")),
    ("/static/style.css", "text/css; charset=utf-8", include_str!("web/style.css")),
    ("/static/app.js", "text/javascript; charset=utf-8", include_str!("web/app.js")),
    ("/static/aurora.js", "text/javascript; charset=utf-8", include_str!("web/aurora.js")),
    ("/static/form.js", "text/javascript; charset=utf-8", include_str!("web/form.js")),
];

/// Serve until interrupted.
pub(crate) fn serve(options: Options) -> Result<String> {
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .context("cannot start the studio's async runtime")?;
    runtime.block_on(async move {
        let addr = SocketAddr::new(options.bind, options.port);
        let listener = tokio::net::TcpListener::bind(addr)
            .await
            .with_context(|| format!("cannot listen on {addr} (is another studio running? try --port)"))?;
        let local = listener.local_addr()?;
        let url = format!("http://{local}/");
        println!("phenomena studio: serving {url}");
        if local.ip().is_loopback() {
            println!("  bound to loopback only: other machines cannot reach it (use --bind to change)");
        } else {
            println!("  WARNING: bound to {}: other machines on the network can reach it", local.ip());
            if local.ip().is_unspecified() {
                println!(
                    "  pages are served only as 127.0.0.1, localhost or the names given with --allow-host"
                );
            }
        }
        println!("  render-final outputs go to {}", options.out.display());
        println!("  press Ctrl-C to stop");
        if options.open {
            open_browser(&url);
        }
        let shared = Arc::new(Shared {
            controls: controls::Catalogue::build(),
            hosts: options.hosts(),
            options,
            sessions: Mutex::new(HashMap::new()),
            counter: AtomicU64::new(0),
            key: std::hash::RandomState::new(),
        });
        axum::serve(listener, router(shared))
            .with_graceful_shutdown(shutdown_signal())
            .await
            .context("the studio server failed")?;
        Ok::<_, anyhow::Error>(())
    })?;
    Ok("phenomena studio stopped".into())
}

/// Ctrl-C, or SIGTERM (what `timeout`, service managers and container runtimes send).
async fn shutdown_signal() {
    #[cfg(unix)]
    {
        let mut term = match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(t) => t,
            Err(_) => {
                let _ = tokio::signal::ctrl_c().await;
                return;
            }
        };
        tokio::select! {
            _ = tokio::signal::ctrl_c() => {}
            _ = term.recv() => {}
        }
    }
    #[cfg(not(unix))]
    {
        let _ = tokio::signal::ctrl_c().await;
    }
}

fn open_browser(url: &str) {
    let tried = std::process::Command::new("xdg-open").arg(url).spawn();
    if tried.is_err() {
        eprintln!("note: could not open a browser (no xdg-open); open {url} yourself");
    }
}

/// The routes, every one behind the `Host` check.
pub(crate) fn router(shared: Arc<Shared>) -> Router {
    Router::new()
        .route("/ws", get(websocket))
        .route("/api/sessions", get(sessions))
        .route("/api/controls", get(controls_catalogue))
        .route("/api/session/{id}/upload/{name}", post(upload).layer(DefaultBodyLimit::max(MAX_UPLOAD_BYTES)))
        .route("/api/session/{id}/snow.glb", get(snow_glb))
        .fallback(get(asset))
        .layer(DefaultBodyLimit::max(MAX_MESSAGE_BYTES))
        .layer(axum::middleware::from_fn_with_state(shared.clone(), known_host))
        .with_state(shared)
}

/// Refuse requests that name a host this studio is not served as: a page of another
/// site whose name was rebound to 127.0.0.1 (DNS rebinding) names its own host.
async fn known_host(
    State(shared): State<Arc<Shared>>,
    request: axum::extract::Request,
    next: axum::middleware::Next,
) -> Response {
    let host = request.headers().get(header::HOST).and_then(|h| h.to_str().ok()).map(host_name);
    match host {
        Some(h) if shared.hosts.contains(&h) => next.run(request).await,
        Some(h) => (
            StatusCode::FORBIDDEN,
            format!("this studio is not served as `{h}`: open it by 127.0.0.1 or localhost, or start it with --allow-host {h}"),
        )
            .into_response(),
        None => (StatusCode::BAD_REQUEST, "the request names no host").into_response(),
    }
}

async fn asset(uri: axum::http::Uri) -> Response {
    match ASSETS.iter().find(|(path, _, _)| *path == uri.path()) {
        Some((_, kind, body)) => {
            ([(header::CONTENT_TYPE, *kind), (header::CACHE_CONTROL, "no-cache")], *body).into_response()
        }
        None => (StatusCode::NOT_FOUND, format!("not found: {}", uri.path())).into_response(),
    }
}

async fn sessions(State(shared): State<Arc<Shared>>) -> Response {
    let ids: Vec<String> = shared.sessions().keys().cloned().collect();
    axum::Json(serde_json::json!({ "live": ids.len(), "max": shared.options.max_sessions })).into_response()
}

async fn controls_catalogue(State(shared): State<Arc<Shared>>) -> Response {
    axum::Json(&shared.controls).into_response()
}

/// A file name an upload may have: letters, digits, spaces, `-`, `_` and dots (a glTF's
/// buffers keep the names it gives them), not starting with a dot or a space, without
/// `..`, at most 100 bytes.
fn safe_name(name: &str) -> bool {
    !name.is_empty()
        && name.len() <= 100
        && !name.starts_with(['.', ' '])
        && !name.contains("..")
        && name.chars().all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.' | ' '))
}

async fn upload(
    State(shared): State<Arc<Shared>>,
    UrlPath((id, name)): UrlPath<(String, String)>,
    body: Bytes,
) -> Response {
    if !safe_name(&name) {
        return (
            StatusCode::BAD_REQUEST,
            format!("upload name `{name}`: use letters, digits, spaces, - _ and dots (not first, no ..)"),
        )
            .into_response();
    }
    let Some(dir) = shared.sessions().get(&id).map(|e| e.dir.clone()) else {
        return (StatusCode::NOT_FOUND, "no such session (was the tab closed?)").into_response();
    };
    let path = dir.join(&name);
    let bytes = body.to_vec();
    let written =
        tokio::task::spawn_blocking(move || phenomena_scene::output::write_bytes_atomic(&path, &bytes)).await;
    match written {
        Ok(Ok(())) => axum::Json(serde_json::json!({ "name": name, "bytes": body.len() })).into_response(),
        // The page is not told the session folder's path; the server's log is.
        Ok(Err(e)) => {
            tracing::error!("upload {name}: {e}");
            (StatusCode::INTERNAL_SERVER_ERROR, format!("cannot store the upload {name}")).into_response()
        }
        Err(e) => {
            tracing::error!("upload {name}: {e}");
            (StatusCode::INTERNAL_SERVER_ERROR, format!("cannot store the upload {name}")).into_response()
        }
    }
}

async fn snow_glb(State(shared): State<Arc<Shared>>, UrlPath(id): UrlPath<String>) -> Response {
    let Some(commands) = shared.sessions().get(&id).map(|e| e.commands.clone()) else {
        return (StatusCode::NOT_FOUND, "no such session (was the tab closed?)").into_response();
    };
    let (reply, answer) = tokio::sync::oneshot::channel();
    if commands.send(Command::SnowGlb(reply)).is_err() {
        return (StatusCode::NOT_FOUND, "the session has ended").into_response();
    }
    match answer.await {
        Ok(Ok(bytes)) => (
            [
                (header::CONTENT_TYPE, "model/gltf-binary"),
                (header::CONTENT_DISPOSITION, "attachment; filename=\"snow.glb\""),
            ],
            bytes,
        )
            .into_response(),
        Ok(Err(message)) => (StatusCode::CONFLICT, message).into_response(),
        Err(_) => (StatusCode::NOT_FOUND, "the session has ended").into_response(),
    }
}

/// Whether a WebSocket handshake comes from this studio's own page (or from a client
/// that sends no `Origin`, i.e. not a browser). Browsers let any site open a socket to
/// 127.0.0.1; this check keeps other sites' pages out.
fn same_origin(headers: &axum::http::HeaderMap) -> bool {
    let Some(origin) = headers.get(header::ORIGIN) else { return true };
    let host = headers.get(header::HOST).and_then(|h| h.to_str().ok()).unwrap_or_default();
    let origin = origin.to_str().unwrap_or_default();
    !host.is_empty() && origin.strip_prefix("http://").is_some_and(|rest| rest == host)
}

async fn websocket(
    State(shared): State<Arc<Shared>>,
    headers: axum::http::HeaderMap,
    upgrade: WebSocketUpgrade,
) -> Response {
    if !same_origin(&headers) {
        return (
            StatusCode::FORBIDDEN,
            "cross-origin WebSocket connections are refused: open the studio's own page",
        )
            .into_response();
    }
    if shared.sessions().len() >= shared.options.max_sessions {
        return (
            StatusCode::SERVICE_UNAVAILABLE,
            format!("the studio serves at most {} tabs at once: close one", shared.options.max_sessions),
        )
            .into_response();
    }
    upgrade
        .max_message_size(MAX_MESSAGE_BYTES)
        .max_frame_size(MAX_MESSAGE_BYTES)
        .on_upgrade(move |socket| run_socket(shared, socket))
}

/// Removes a session from the registry when its simulation thread ends.
struct Deregister {
    shared: Arc<Shared>,
    id: String,
}

impl Drop for Deregister {
    fn drop(&mut self) {
        self.shared.sessions().remove(&self.id);
    }
}

async fn run_socket(shared: Arc<Shared>, socket: WebSocket) {
    let (mut tx, mut rx) = socket.split();
    let Some((commands, mut outgoing)) = start_session(&shared, &mut tx).await else { return };
    relay(&mut tx, &mut rx, &commands, &mut outgoing).await;
    // The session thread ends (removing the session from the registry and deleting its
    // folder) on this message, or on its next frame when the receiver is gone.
    let _ = commands.send(Command::Close);
}

/// The socket's sending half.
type Tx = futures_util::stream::SplitSink<WebSocket, Message>;

/// Send `message` as an error to the page; `false` when the page is gone.
async fn send_error(tx: &mut Tx, message: &str) -> bool {
    let msg = serde_json::json!({"type": "error", "message": message});
    tx.send(Message::Text(msg.to_string().into())).await.is_ok()
}

/// Register a session with its folder and its share of the memory budget, start its
/// thread and greet the page; returns where its commands go and where its messages
/// come from (`None`: it could not start, the page was told when it could be).
async fn start_session(
    shared: &Arc<Shared>,
    tx: &mut Tx,
) -> Option<(std::sync::mpsc::Sender<Command>, tokio::sync::mpsc::Receiver<session::Out>)> {
    let n = shared.counter.fetch_add(1, Ordering::Relaxed);
    let id = format!("{:016x}", shared.key.hash_one(n));
    let dir = match tempfile::Builder::new().prefix("phenomena-studio-").tempdir() {
        Ok(d) => d,
        Err(e) => {
            send_error(tx, &format!("cannot make a session folder: {e}")).await;
            return None;
        }
    };
    let (commands, inbox) = std::sync::mpsc::channel::<Command>();
    // Two frames in flight at most: a slow page slows the simulation instead of
    // queueing stale frames.
    let (outbox, outgoing) = tokio::sync::mpsc::channel::<session::Out>(2);
    shared.sessions().insert(id.clone(), Entry { dir: dir.path().to_path_buf(), commands: commands.clone() });
    let guard = Deregister { shared: shared.clone(), id: id.clone() };
    let hello = session::hello(&id, &shared.controls);
    let out_root = shared.options.out.clone();
    // Each of the sessions the studio serves at once gets its share of the budget.
    let budget = crate::render::limits().memory_bytes;
    let limits = phenomena_scene::Limits { memory_bytes: budget / shared.options.max_sessions.max(1) as u64 };
    let thread = std::thread::Builder::new().name(format!("studio-{id}")).spawn(move || {
        let _guard = guard;
        session::run(dir, out_root, limits, inbox, outbox);
    });
    if let Err(e) = thread {
        tracing::error!("cannot start a session thread: {e}");
        return None;
    }
    tx.send(Message::Text(hello.into())).await.ok()?;
    Some((commands, outgoing))
}

/// Pass the page's messages to the session and the session's to the page until either
/// is gone.
async fn relay(
    tx: &mut Tx,
    rx: &mut futures_util::stream::SplitStream<WebSocket>,
    commands: &std::sync::mpsc::Sender<Command>,
    outgoing: &mut tokio::sync::mpsc::Receiver<session::Out>,
) {
    loop {
        tokio::select! {
            incoming = rx.next() => match incoming {
                Some(Ok(Message::Text(text))) => match session::parse_command(&text) {
                    Ok(command) => {
                        if commands.send(command).is_err() {
                            break;
                        }
                    }
                    Err(message) => {
                        if !send_error(tx, &message).await {
                            break;
                        }
                    }
                },
                Some(Ok(Message::Binary(_))) => {
                    if !send_error(tx, "binary messages are not understood: send JSON text").await {
                        break;
                    }
                }
                Some(Ok(_)) => {}
                Some(Err(_)) | None => break,
            },
            out = outgoing.recv() => {
                let sent = match out {
                    Some(session::Out::Text(t)) => tx.send(Message::Text(t.into())).await,
                    Some(session::Out::Binary(b)) => tx.send(Message::Binary(b.into())).await,
                    None => break,
                };
                if sent.is_err() {
                    break;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests;
