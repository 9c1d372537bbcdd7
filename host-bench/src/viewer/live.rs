//! `--live [ADDR]`: the run served while it goes, on one port (default 127.0.0.1:8765):
//! * a Foxglove WebSocket server (the protocol's v1: `serverInfo`, `advertise`, `subscribe`,
//!   `unsubscribe`, binary message data) for Foxglove and Lichtblick. Both subprotocol names
//!   in use are accepted: `foxglove.websocket.v1` (Lichtblick, the protocol's own clients) and
//!   `foxglove.sdk.v1` (Foxglove's SDK); the message framing of the two is the same.
//! * the bench page, for a browser with no viewer installed: `GET /` serves `page.html`, which
//!   connects back to the same port and draws the run.
//!
//! Plain threads: one accepting, one per client, at most [`MAX_CONNECTIONS`]. Whatever a client
//! does, the run is never held up and memory stays bounded: the run's thread only queues (a
//! client's queue holds [`CLIENT_QUEUE`] messages; a slow client loses messages, counted, and
//! one that stops reading is dropped after [`WRITE_TIMEOUT`]), a request head must arrive whole
//! within [`HEAD_TIMEOUT`], a client's message is at most [`MAX_CLIENT_MESSAGE`] bytes. Each
//! channel keeps its last [`HISTORY`] messages for the page (`GET /history`, in time order), so
//! a page opened part way through a run still draws it from the start; a WebSocket client gets
//! what is logged from its subscription on, as the protocol's players expect (a message older
//! than the last they had reads to them as a seek).

use std::collections::{HashMap, VecDeque};
use std::io::{Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, SyncSender, TrySendError};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::{Context as _, Result};
use serde_json::json;
use tungstenite::handshake::server::{ErrorResponse, Request, Response};
use tungstenite::protocol::WebSocketConfig;
use tungstenite::{Message, WebSocket};

use super::{Channel, Sink};

/// The default address: this machine only. Another interface only when asked for.
pub const DEFAULT_ADDR: &str = "127.0.0.1:8765";
/// The subprotocol names accepted, in order of preference.
pub const SUBPROTOCOLS: [&str; 2] = ["foxglove.websocket.v1", "foxglove.sdk.v1"];
/// Messages queued for one client before it loses some.
pub const CLIENT_QUEUE: usize = 4096;
/// Messages kept per channel for the page's `GET /history`.
pub const HISTORY: usize = 20_000;
/// Connections served at once; more are answered 503.
pub const MAX_CONNECTIONS: usize = 32;
/// The largest HTTP request head read (a browser's is under 2 KiB).
const MAX_HEAD: usize = 16 * 1024;
/// How long a request head may take to arrive, whole.
pub const HEAD_TIMEOUT: Duration = Duration::from_secs(5);
/// A client that takes no bytes for this long is dropped.
pub const WRITE_TIMEOUT: Duration = Duration::from_secs(5);
/// The largest message a client may send (a subscribe of every channel is under 4 KiB).
pub const MAX_CLIENT_MESSAGE: usize = 64 * 1024;

const PAGE: &str = include_str!("page.html");

/// The live server. Cloned handles share it; one is the run's [`Sink`].
#[derive(Clone)]
pub struct LiveServer {
    shared: Arc<Mutex<Shared>>,
    addr: SocketAddr,
    connections: Arc<AtomicUsize>,
}

#[derive(Default)]
struct Shared {
    channels: Vec<Channel>,
    history: Vec<VecDeque<(u64, Arc<[u8]>)>>,
    clients: Vec<Client>,
    next_client: u64,
    /// Messages a slow client did not get.
    dropped: u64,
    /// What the command says of the run (`running`, `done`, ...), for the page.
    state: String,
}

struct Client {
    id: u64,
    tx: SyncSender<Message>,
    /// Channel index → this client's subscription id.
    subscribed: HashMap<usize, u32>,
}

impl LiveServer {
    /// Binds `addr` and starts serving. Errors name the address (in use, not this machine's).
    pub fn start(addr: &str) -> Result<Self> {
        let listener = TcpListener::bind(addr)
            .with_context(|| format!("--live {addr}: cannot listen there"))?;
        let addr = listener.local_addr()?;
        let server = LiveServer {
            shared: Arc::new(Mutex::new(Shared {
                state: "starting".into(),
                ..Default::default()
            })),
            addr,
            connections: Arc::default(),
        };
        let s = server.clone();
        std::thread::Builder::new()
            .name("live-accept".into())
            .spawn(move || {
                for stream in listener.incoming() {
                    let Ok(mut stream) = stream else {
                        // Out of descriptors, say: try again in a while, not in a loop.
                        std::thread::sleep(Duration::from_millis(100));
                        continue;
                    };
                    if s.connections.fetch_add(1, Ordering::SeqCst) >= MAX_CONNECTIONS {
                        s.connections.fetch_sub(1, Ordering::SeqCst);
                        let _ = stream.set_write_timeout(Some(WRITE_TIMEOUT));
                        let _ = stream.write_all(
                            b"HTTP/1.1 503 Service Unavailable\r\nContent-Length: 0\r\n\r\n",
                        );
                        continue;
                    }
                    let s = s.clone();
                    let spawned = std::thread::Builder::new()
                        .name("live-client".into())
                        .spawn(move || {
                            s.serve(stream);
                            s.connections.fetch_sub(1, Ordering::SeqCst);
                        });
                    if spawned.is_err() {
                        // The closure (and its count) went with the failed spawn.
                        std::thread::sleep(Duration::from_millis(100));
                    }
                }
            })?;
        Ok(server)
    }

    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    pub fn sink(&self) -> Box<dyn Sink> {
        Box::new(self.clone())
    }

    /// What the run is doing, shown by the page (`running`, `done: 0.02 mm`, ...).
    pub fn set_state(&self, state: &str) {
        let mut sh = self.lock();
        sh.state = state.to_string();
        let msg = Message::text(status_json(&sh.state));
        // A full queue loses this message; only a client that is gone is let go.
        sh.clients.retain(|c| {
            !matches!(
                c.tx.try_send(msg.clone()),
                Err(TrySendError::Disconnected(_))
            )
        });
    }

    /// Messages slow clients did not get.
    pub fn dropped(&self) -> u64 {
        self.lock().dropped
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Shared> {
        self.shared.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// One connection: the bench page or its history over HTTP, or a WebSocket client.
    fn serve(&self, mut stream: TcpStream) {
        let _ = stream.set_write_timeout(Some(WRITE_TIMEOUT));
        let Ok(head) = read_head(&mut stream) else {
            return;
        };
        let text = String::from_utf8_lossy(&head).to_ascii_lowercase();
        let upgrade = text
            .lines()
            .any(|l| l.starts_with("upgrade:") && l.contains("websocket"));
        if !upgrade {
            let path = text.split_whitespace().nth(1).unwrap_or("");
            let _ = if path == "/history" {
                self.serve_history(&mut stream)
            } else {
                serve_page(&mut stream, path)
            };
            return;
        }
        let replay = Replayed {
            head: std::io::Cursor::new(head),
            stream,
        };
        let config = WebSocketConfig::default()
            .max_message_size(Some(MAX_CLIENT_MESSAGE))
            .max_frame_size(Some(MAX_CLIENT_MESSAGE));
        let Ok(ws) = tungstenite::accept_hdr_with_config(replay, choose_subprotocol, Some(config))
        else {
            return;
        };
        let _ = self.run_client(ws);
    }

    /// `GET /history`: what each channel kept, in time order, as
    /// `{"messages": [[channel, t_ns, message], ...]}`. Taken under the lock as shared
    /// pointers; written out after it.
    fn serve_history(&self, stream: &mut TcpStream) -> std::io::Result<()> {
        let mut all: Vec<(u64, usize, Arc<[u8]>)> = {
            let sh = self.lock();
            (sh.history.iter().enumerate())
                .flat_map(|(ch, h)| h.iter().map(move |(t, d)| (*t, ch, d.clone())))
                .collect()
        };
        all.sort_by_key(|(t, ch, _)| (*t, *ch));
        let mut out = std::io::BufWriter::new(stream);
        write!(
            out,
            "HTTP/1.1 200 OK\r\nContent-Type: application/json\r\nCache-Control: no-store\r\n\
             Connection: close\r\n\r\n{{\"messages\":["
        )?;
        for (i, (t, ch, data)) in all.iter().enumerate() {
            write!(out, "{}[{ch},{t},", if i > 0 { "," } else { "" })?;
            out.write_all(data)?;
            out.write_all(b"]")?;
        }
        out.write_all(b"]}")?;
        out.flush()
    }

    fn run_client(&self, mut ws: WebSocket<Replayed>) -> Result<()> {
        ws.get_mut()
            .stream
            .set_read_timeout(Some(Duration::from_millis(20)))?;
        let (tx, rx) = sync_channel(CLIENT_QUEUE);
        let id = {
            // Queued, not sent: no socket is written while the lock is held.
            let mut sh = self.lock();
            let id = sh.next_client;
            sh.next_client += 1;
            let _ = tx.try_send(Message::text(server_info()));
            let _ = tx.try_send(Message::text(status_json(&sh.state)));
            if !sh.channels.is_empty() {
                let _ = tx.try_send(Message::text(advertise(&sh.channels)));
            }
            sh.clients.push(Client {
                id,
                tx,
                subscribed: HashMap::new(),
            });
            id
        };
        let result = self.client_loop(&mut ws, id, &rx);
        self.lock().clients.retain(|c| c.id != id);
        result
    }

    fn client_loop(
        &self,
        ws: &mut WebSocket<Replayed>,
        id: u64,
        rx: &Receiver<Message>,
    ) -> Result<()> {
        loop {
            while let Ok(m) = rx.try_recv() {
                // A client that takes nothing for WRITE_TIMEOUT ends here, with an error.
                ws.send(m)?;
            }
            match ws.read() {
                Ok(Message::Text(t)) => self.on_request(id, t.as_str()),
                Ok(Message::Close(_)) => {
                    // The close handshake's reply, queued by the read.
                    let _ = ws.flush();
                    return Ok(());
                }
                Ok(_) => {}
                Err(tungstenite::Error::Io(e))
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                    ) => {}
                Err(e) => return Err(e.into()),
            }
        }
    }

    /// A client's JSON request: subscribe and unsubscribe (the rest of the protocol, client
    /// publishing, parameters, services, is not offered in `serverInfo`'s capabilities). A
    /// subscription takes what is logged from now on.
    fn on_request(&self, id: u64, text: &str) {
        let Ok(req) = serde_json::from_str::<serde_json::Value>(text) else {
            return;
        };
        let mut sh = self.lock();
        let channels = sh.channels.len();
        let Some(client) = sh.clients.iter_mut().find(|c| c.id == id) else {
            return;
        };
        match req["op"].as_str() {
            Some("subscribe") => {
                for s in req["subscriptions"].as_array().into_iter().flatten() {
                    let (Some(sub), Some(ch)) = (s["id"].as_u64(), s["channelId"].as_u64()) else {
                        continue;
                    };
                    // One subscription a channel: a channel named again takes the new id.
                    if (ch as usize) < channels {
                        client.subscribed.insert(ch as usize, sub as u32);
                    }
                }
            }
            Some("unsubscribe") => {
                for sub in req["subscriptionIds"].as_array().into_iter().flatten() {
                    client
                        .subscribed
                        .retain(|_, s| Some(*s as u64) != sub.as_u64());
                }
            }
            _ => {}
        }
    }
}

impl Sink for LiveServer {
    fn start(&mut self, channels: &[Channel]) -> Result<()> {
        let mut sh = self.lock();
        sh.channels = channels.to_vec();
        sh.history = vec![VecDeque::new(); channels.len()];
        sh.state = "running".into();
        let adv = Message::text(advertise(channels));
        let status = Message::text(status_json(&sh.state));
        for c in &sh.clients {
            let _ = c.tx.try_send(adv.clone());
            let _ = c.tx.try_send(status.clone());
        }
        Ok(())
    }

    fn message(&mut self, id: usize, t_ns: u64, data: &[u8]) -> Result<()> {
        let mut sh = self.lock();
        let data: Arc<[u8]> = data.into();
        let Some(h) = sh.history.get_mut(id) else {
            return Ok(());
        };
        if h.len() == HISTORY {
            h.pop_front();
        }
        h.push_back((t_ns, data.clone()));
        let mut dropped = 0;
        for c in &sh.clients {
            if let Some(&sub) = c.subscribed.get(&id) {
                if let Err(TrySendError::Full(_)) = c.tx.try_send(data_message(sub, t_ns, &data)) {
                    dropped += 1;
                }
            }
        }
        sh.dropped += dropped;
        Ok(())
    }
}

/// The protocol's binary message data: opcode 1, subscription id, log time, payload.
fn data_message(sub: u32, t_ns: u64, data: &[u8]) -> Message {
    let mut b = Vec::with_capacity(13 + data.len());
    b.push(1);
    b.extend_from_slice(&sub.to_le_bytes());
    b.extend_from_slice(&t_ns.to_le_bytes());
    b.extend_from_slice(data);
    Message::binary(b)
}

fn server_info() -> String {
    json!({
        "op": "serverInfo",
        "name": format!("omnibench host-bench {}", env!("CARGO_PKG_VERSION")),
        "capabilities": [],
        "supportedEncodings": [],
        "metadata": {},
    })
    .to_string()
}

/// The run's state as the protocol's `status` message (level 0, info), which Foxglove shows
/// in its problems list and the page in its header.
fn status_json(state: &str) -> String {
    json!({"op": "status", "level": 0, "message": state, "id": "run"}).to_string()
}

fn advertise(channels: &[Channel]) -> String {
    let list: Vec<_> = (channels.iter().enumerate())
        .map(|(id, c)| {
            json!({
                "id": id,
                "topic": c.topic,
                "encoding": "json",
                "schemaName": c.schema_name,
                "schema": c.schema,
                "schemaEncoding": "jsonschema",
            })
        })
        .collect();
    json!({"op": "advertise", "channels": list}).to_string()
}

/// The handshake's subprotocol: the first of ours the client offers; a client offering none
/// of them gets 400, as the protocol asks.
#[allow(clippy::result_large_err)] // tungstenite's callback type
fn choose_subprotocol(req: &Request, mut res: Response) -> Result<Response, ErrorResponse> {
    let offered: Vec<String> = (req.headers().get_all("sec-websocket-protocol").iter())
        .filter_map(|h| h.to_str().ok())
        .flat_map(|h| h.split(',').map(|p| p.trim().to_string()))
        .collect();
    match SUBPROTOCOLS
        .iter()
        .find(|p| offered.iter().any(|o| o == *p))
    {
        Some(p) => {
            res.headers_mut()
                .insert("sec-websocket-protocol", p.parse().expect("a valid header"));
            Ok(res)
        }
        None => {
            let mut e = ErrorResponse::new(Some(format!(
                "offer one of these subprotocols: {}",
                SUBPROTOCOLS.join(", ")
            )));
            *e.status_mut() = tungstenite::http::StatusCode::BAD_REQUEST;
            Err(e)
        }
    }
}

/// The request head, up to its blank line, whole within [`HEAD_TIMEOUT`].
fn read_head(stream: &mut TcpStream) -> std::io::Result<Vec<u8>> {
    let deadline = Instant::now() + HEAD_TIMEOUT;
    let mut head = Vec::new();
    let mut buf = [0u8; 1024];
    loop {
        let left = deadline
            .checked_duration_since(Instant::now())
            .filter(|d| !d.is_zero())
            .ok_or(std::io::ErrorKind::TimedOut)?;
        stream.set_read_timeout(Some(left))?;
        let n = stream.read(&mut buf)?;
        if n == 0 {
            return Err(std::io::ErrorKind::UnexpectedEof.into());
        }
        // Only the new bytes and the three before them can complete the blank line.
        let from = head.len().saturating_sub(3);
        head.extend_from_slice(&buf[..n]);
        if head[from..].windows(4).any(|w| w == b"\r\n\r\n") {
            return Ok(head);
        }
        if head.len() > MAX_HEAD {
            return Err(std::io::ErrorKind::InvalidData.into());
        }
    }
}

/// `GET /` is the page; anything else 404.
fn serve_page(stream: &mut TcpStream, path: &str) -> std::io::Result<()> {
    let path = path.split('?').next().unwrap_or("");
    let (status, kind, body) = if path == "/" || path == "/index.html" {
        ("200 OK", "text/html; charset=utf-8", PAGE)
    } else {
        (
            "404 Not Found",
            "text/plain",
            "not here: the bench page is at /\n",
        )
    };
    write!(
        stream,
        "HTTP/1.1 {status}\r\nContent-Type: {kind}\r\nContent-Length: {}\r\n\
         Cache-Control: no-store\r\nConnection: close\r\n\r\n{body}",
        body.len()
    )?;
    stream.flush()
}

/// The connection with the request head already read put back in front, for the handshake.
struct Replayed {
    head: std::io::Cursor<Vec<u8>>,
    stream: TcpStream,
}

impl Read for Replayed {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        if (self.head.position() as usize) < self.head.get_ref().len() {
            return self.head.read(buf);
        }
        self.stream.read(buf)
    }
}

impl Write for Replayed {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.stream.write(buf)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.stream.flush()
    }
}
