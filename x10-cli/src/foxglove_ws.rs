//! The live run for Foxglove's *Open connection*: a WebSocket server speaking the Foxglove
//! WebSocket protocol (subprotocol `foxglove.websocket.v1`), publishing the same messages as
//! the MCAP file ([`crate::foxglove`]) as they come. Behind the cargo feature `foxglove-live`
//! (off by default: its WebSocket library, `tungstenite`, is built only when asked for).
//!
//! What the server says and takes (the protocol's JSON and binary messages):
//! * to each client on connecting: `serverInfo`, then `advertise` with every channel so far;
//! * to every client when a topic is first published: `advertise` with its channel (JSON
//!   encoding, its JSON schema);
//! * from a client: `subscribe` (`{"op":"subscribe","subscriptions":[{"id":S,"channelId":C}]}`)
//!   and `unsubscribe` (`{"op":"unsubscribe","subscriptionIds":[S]}`);
//! * to a client, for each message on a channel it subscribed to: a binary frame, opcode 1,
//!   the subscription id (u32, little-endian), the log time (u64 ns, little-endian), the JSON.
//!
//! One thread serves every client, with non-blocking sockets: a slow client never holds up
//! the monitor (what it cannot take waits in its write buffer, up to [`MAX_BUFFERED`] bytes;
//! past that its messages are dropped and counted).

use std::collections::HashMap;
use std::net::{SocketAddr, TcpListener, TcpStream, ToSocketAddrs};
use std::sync::mpsc::{channel, Receiver, RecvTimeoutError, Sender};
use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use serde_json::{json, Value};
use tungstenite::handshake::server::{ErrorResponse, Request, Response};
use tungstenite::http::HeaderValue;
use tungstenite::{Message as WsMessage, WebSocket};

use crate::foxglove::Message;

/// The WebSocket subprotocol of the Foxglove WebSocket protocol.
pub const SUBPROTOCOL: &str = "foxglove.websocket.v1";

/// What a client that does not keep up may have waiting in its write buffer (bytes); past
/// that its messages are dropped and counted ([`LiveStats::dropped`]).
pub const MAX_BUFFERED: usize = 4 << 20;

/// Foxglove's default address for *Open connection* (`ws://localhost:8765`).
pub const DEFAULT_ADDR: &str = "127.0.0.1:8765";

/// The binary frame of a message for subscription `sub`: opcode 1, `sub` (u32 LE), the log
/// time (u64 LE), the JSON.
pub fn message_frame(sub: u32, log_time_ns: u64, json: &[u8]) -> Vec<u8> {
    let mut f = Vec::with_capacity(13 + json.len());
    f.push(0x01);
    f.extend_from_slice(&sub.to_le_bytes());
    f.extend_from_slice(&log_time_ns.to_le_bytes());
    f.extend_from_slice(json);
    f
}

/// A channel as `advertise` describes it.
fn channel_json(id: u32, m: &Message) -> Value {
    json!({
        "id": id,
        "topic": m.topic,
        "encoding": "json",
        "schemaName": m.schema.name,
        "schema": m.schema.json,
        "schemaEncoding": "jsonschema",
    })
}

/// What the server counts (for the summary and the tests).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LiveStats {
    /// Clients connected so far.
    pub clients: u64,
    /// Subscriptions taken so far.
    pub subscriptions: u64,
    /// Message frames sent.
    pub sent: u64,
    /// Message frames a client could not take (its write buffer full) or that failed.
    pub dropped: u64,
    /// Connections refused (no Foxglove subprotocol, a failed handshake).
    pub refused: u64,
    /// Calls of [`LiveServer::advertise`] served.
    pub advertised: u64,
}

struct Client {
    ws: WebSocket<TcpStream>,
    /// Subscription id by channel id.
    subs: HashMap<u32, u32>,
}

enum Cmd {
    Advertise(Vec<Message>),
    Publish(Message),
    Stop,
}

type Shared = Arc<(Mutex<LiveStats>, Condvar)>;

/// The server: [`LiveServer::publish`] hands it messages; its thread serves the clients.
pub struct LiveServer {
    tx: Sender<Cmd>,
    addr: SocketAddr,
    stats: Shared,
    thread: Option<JoinHandle<()>>,
}

impl std::fmt::Debug for LiveServer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LiveServer")
            .field("addr", &self.addr)
            .finish_non_exhaustive()
    }
}

impl LiveServer {
    /// Listens on `addr` (`127.0.0.1:8765`; port 0 for any free one).
    ///
    /// # Errors
    /// The address cannot be bound.
    pub fn start(addr: impl ToSocketAddrs, name: &str) -> std::io::Result<LiveServer> {
        let listener = TcpListener::bind(addr)?;
        listener.set_nonblocking(true)?;
        let addr = listener.local_addr()?;
        let (tx, rx) = channel();
        let stats: Shared = Arc::new((Mutex::new(LiveStats::default()), Condvar::new()));
        let shared = stats.clone();
        let name = name.to_string();
        let thread = std::thread::Builder::new()
            .name("foxglove-ws".into())
            .spawn(move || serve(&listener, &rx, &shared, &name))?;
        Ok(LiveServer {
            tx,
            addr,
            stats,
            thread: Some(thread),
        })
    }

    /// The address it listens on.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// Hands `m` to the server (sent to the clients subscribed to its topic).
    pub fn publish(&self, m: Message) {
        // The thread ends only with the server: a send cannot fail before.
        let _ = self.tx.send(Cmd::Publish(m));
    }

    /// Advertises the topics of `messages` (their channels, to every client now and to
    /// come) without sending them: a run known in advance shows all its topics at once.
    /// Returns when the server has them.
    pub fn advertise(&self, messages: &[Message]) {
        let (lock, cv) = &*self.stats;
        let before = lock.lock().map(|s| s.advertised).unwrap_or(0);
        if self.tx.send(Cmd::Advertise(messages.to_vec())).is_err() {
            return;
        }
        if let Ok(guard) = lock.lock() {
            let _unused = cv.wait_while(guard, |s| s.advertised == before);
        }
    }

    /// Plays `messages` (in time order) at the pace of their log times, from the first one on,
    /// once a client subscribed (the simulator's run, live: `x10 sim --foxglove-ws`). Every
    /// topic is advertised first. Returns when the last message was handed over.
    pub fn play(&self, messages: &[Message], speed: f64) {
        self.advertise(messages);
        let (lock, cv) = &*self.stats;
        if let Ok(guard) = lock.lock() {
            let _unused = cv.wait_while(guard, |s| s.subscriptions == 0);
        }
        let start = std::time::Instant::now();
        let first = messages.first().map_or(0, |m| m.log_time_ns);
        for m in messages {
            let due = (m.log_time_ns.saturating_sub(first) as f64 / speed.max(1e-6)) as u64;
            let due = Duration::from_nanos(due);
            let now = start.elapsed();
            if due > now {
                std::thread::sleep(due - now);
            }
            self.publish(m.clone());
        }
    }

    /// The counts so far.
    pub fn stats(&self) -> LiveStats {
        self.stats.0.lock().map(|s| *s).unwrap_or_default()
    }

    /// Waits until `n` subscriptions were taken in all, at most `timeout`; true when they
    /// were.
    pub fn wait_subscriptions(&self, n: u64, timeout: Duration) -> bool {
        let (lock, cv) = &*self.stats;
        let Ok(guard) = lock.lock() else {
            return false;
        };
        cv.wait_timeout_while(guard, timeout, |s| s.subscriptions < n)
            .map(|(s, _)| s.subscriptions >= n)
            .unwrap_or(false)
    }
}

impl Drop for LiveServer {
    fn drop(&mut self) {
        let _ = self.tx.send(Cmd::Stop);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

fn count(shared: &Shared, f: impl FnOnce(&mut LiveStats)) {
    let (lock, cv) = &**shared;
    if let Ok(mut s) = lock.lock() {
        f(&mut s);
    }
    cv.notify_all();
}

/// The handshake's check: the Foxglove subprotocol is required and answered. (The error
/// type is tungstenite's `Callback`'s: an HTTP response, large.)
#[allow(clippy::result_large_err)]
fn check_subprotocol(req: &Request, mut resp: Response) -> Result<Response, ErrorResponse> {
    let offered = req
        .headers()
        .get_all("Sec-WebSocket-Protocol")
        .iter()
        .filter_map(|v| v.to_str().ok())
        .flat_map(|v| v.split(','))
        .any(|p| p.trim() == SUBPROTOCOL);
    if !offered {
        let mut e = ErrorResponse::new(Some(format!("subprotocol {SUBPROTOCOL} required")));
        *e.status_mut() = tungstenite::http::StatusCode::BAD_REQUEST;
        return Err(e);
    }
    resp.headers_mut().insert(
        "Sec-WebSocket-Protocol",
        HeaderValue::from_static(SUBPROTOCOL),
    );
    Ok(resp)
}

/// The handshake (blocking, 2 s at most for the request), then the socket non-blocking.
fn accept(stream: TcpStream) -> Option<WebSocket<TcpStream>> {
    stream.set_nonblocking(false).ok()?;
    stream.set_read_timeout(Some(Duration::from_secs(2))).ok()?;
    let config =
        tungstenite::protocol::WebSocketConfig::default().max_write_buffer_size(MAX_BUFFERED);
    let ws = tungstenite::accept_hdr_with_config(stream, check_subprotocol, Some(config)).ok()?;
    ws.get_ref().set_nonblocking(true).ok()?;
    Some(ws)
}

fn send_text(c: &mut Client, v: &Value) -> bool {
    c.ws.send(WsMessage::text(v.to_string())).is_ok() || would_block_only(c)
}

/// After a failed write: true when the socket only would block (the frame is buffered).
fn would_block_only(c: &mut Client) -> bool {
    match c.ws.flush() {
        Ok(()) => true,
        Err(tungstenite::Error::Io(e)) => e.kind() == std::io::ErrorKind::WouldBlock,
        Err(_) => false,
    }
}

fn serve(listener: &TcpListener, rx: &Receiver<Cmd>, shared: &Shared, name: &str) {
    let mut clients: Vec<Client> = Vec::new();
    // Channels by topic: (id, the advertisement).
    let mut channels: HashMap<String, (u32, Value)> = HashMap::new();
    loop {
        // New clients: hello and the channels so far.
        while let Ok((stream, _)) = listener.accept() {
            let Some(ws) = accept(stream) else {
                count(shared, |s| s.refused += 1);
                continue;
            };
            let mut c = Client {
                ws,
                subs: HashMap::new(),
            };
            let info = json!({
                "op": "serverInfo",
                "name": name,
                "capabilities": [],
                "supportedEncodings": [],
                "metadata": {},
            });
            let mut ads: Vec<(u32, Value)> = channels.values().cloned().collect();
            ads.sort_by_key(|(id, _)| *id);
            let ads: Vec<Value> = ads.into_iter().map(|(_, v)| v).collect();
            let ok = send_text(&mut c, &info)
                && (ads.is_empty()
                    || send_text(&mut c, &json!({"op": "advertise", "channels": ads})));
            if ok {
                count(shared, |s| s.clients += 1);
                clients.push(c);
            }
        }
        // What the clients asked.
        clients.retain_mut(|c| read_requests(c, shared));
        match rx.recv_timeout(Duration::from_millis(5)) {
            Ok(Cmd::Advertise(messages)) => {
                for m in messages {
                    if !channels.contains_key(&m.topic) {
                        let id = u32::try_from(channels.len() + 1).unwrap_or(u32::MAX);
                        channels.insert(m.topic.clone(), (id, channel_json(id, &m)));
                        let ad = json!({"op": "advertise", "channels": [channel_json(id, &m)]});
                        clients.retain_mut(|c| send_text(c, &ad));
                    }
                }
                count(shared, |s| s.advertised += 1);
            }
            Ok(Cmd::Publish(m)) => {
                let next = u32::try_from(channels.len() + 1).unwrap_or(u32::MAX);
                let (id, new) = match channels.get(&m.topic) {
                    Some((id, _)) => (*id, false),
                    None => {
                        channels.insert(m.topic.clone(), (next, channel_json(next, &m)));
                        (next, true)
                    }
                };
                if new {
                    let ad = json!({"op": "advertise", "channels": [channel_json(id, &m)]});
                    clients.retain_mut(|c| send_text(c, &ad));
                }
                let data = m.data.to_string();
                for c in &mut clients {
                    let Some(sub) = c.subs.get(&id) else {
                        continue;
                    };
                    let frame = message_frame(*sub, m.log_time_ns, data.as_bytes());
                    match c.ws.write(WsMessage::binary(frame)) {
                        Ok(()) => count(shared, |s| s.sent += 1),
                        Err(tungstenite::Error::Io(e))
                            if e.kind() == std::io::ErrorKind::WouldBlock =>
                        {
                            count(shared, |s| s.sent += 1);
                        }
                        Err(_) => count(shared, |s| s.dropped += 1),
                    }
                }
            }
            Ok(Cmd::Stop) | Err(RecvTimeoutError::Disconnected) => break,
            Err(RecvTimeoutError::Timeout) => {}
        }
        clients.retain_mut(would_block_only);
    }
    for c in &mut clients {
        let _ = c.ws.close(None);
        let _ = c.ws.flush();
    }
}

/// Reads what `c` sent (subscribe, unsubscribe); false when it went away.
fn read_requests(c: &mut Client, shared: &Shared) -> bool {
    loop {
        match c.ws.read() {
            Ok(WsMessage::Text(t)) => {
                let Ok(v) = serde_json::from_str::<Value>(t.as_str()) else {
                    continue;
                };
                match v.get("op").and_then(Value::as_str) {
                    Some("subscribe") => {
                        for s in v["subscriptions"].as_array().into_iter().flatten() {
                            let (Some(id), Some(ch)) = (
                                s["id"].as_u64().and_then(|x| u32::try_from(x).ok()),
                                s["channelId"].as_u64().and_then(|x| u32::try_from(x).ok()),
                            ) else {
                                continue;
                            };
                            c.subs.insert(ch, id);
                            count(shared, |s| s.subscriptions += 1);
                        }
                    }
                    Some("unsubscribe") => {
                        for id in v["subscriptionIds"].as_array().into_iter().flatten() {
                            let id = id.as_u64();
                            c.subs.retain(|_, s| Some(u64::from(*s)) != id);
                        }
                    }
                    _ => {}
                }
            }
            Ok(WsMessage::Close(_)) => return false,
            Ok(_) => {}
            Err(tungstenite::Error::Io(e)) if e.kind() == std::io::ErrorKind::WouldBlock => {
                return true
            }
            Err(_) => return false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::foxglove::{output_message, CALLS_TOPIC};
    use x10_microcode::Port;
    use x10_sim::ports::{Change, OutputChange};

    fn text(ws: &mut WebSocket<TcpStream>) -> Value {
        loop {
            match ws.read().unwrap() {
                WsMessage::Text(t) => return serde_json::from_str(t.as_str()).unwrap(),
                WsMessage::Ping(_) | WsMessage::Pong(_) => {}
                other => panic!("{other:?}"),
            }
        }
    }

    fn connect(addr: SocketAddr) -> WebSocket<TcpStream> {
        use tungstenite::client::IntoClientRequest;
        let mut req = format!("ws://{addr}").into_client_request().unwrap();
        req.headers_mut().insert(
            "Sec-WebSocket-Protocol",
            HeaderValue::from_static(SUBPROTOCOL),
        );
        let stream = TcpStream::connect(addr).unwrap();
        stream
            .set_read_timeout(Some(Duration::from_secs(10)))
            .unwrap();
        let (ws, resp) = tungstenite::client(req, stream).unwrap();
        assert_eq!(
            resp.headers().get("Sec-WebSocket-Protocol").unwrap(),
            SUBPROTOCOL
        );
        ws
    }

    fn pwm(t_ns: u64, duty: u8) -> Message {
        let c = OutputChange {
            t_ns,
            board: "db09".into(),
            pin: Port::actuator(1).unwrap().pin(x10_microcode::Pin::A),
            change: Change::Duty(duty),
        };
        output_message(&c, Some("light_motor"))
    }

    #[test]
    fn a_foxglove_client_subscribes_and_gets_the_motor_live() {
        let server = LiveServer::start("127.0.0.1:0", "x10 test").unwrap();
        let mut ws = connect(server.addr());
        let info = text(&mut ws);
        assert_eq!(info["op"], "serverInfo");
        assert_eq!(info["name"], "x10 test");
        // A first message on a new topic: advertised (to a client not subscribed: no data).
        server.publish(pwm(1_942_704_825, 127));
        let ad = text(&mut ws);
        assert_eq!(ad["op"], "advertise");
        let ch = &ad["channels"][0];
        assert_eq!(ch["id"], 1);
        assert_eq!(ch["topic"], "/x10/outputs/db09/A1_A/pwm");
        assert_eq!(ch["encoding"], "json");
        assert_eq!(ch["schemaName"], "x10.Output");
        assert_eq!(ch["schemaEncoding"], "jsonschema");
        assert_eq!(ch["schema"], crate::foxglove::OUTPUT.json);
        ws.send(WsMessage::text(
            r#"{"op":"subscribe","subscriptions":[{"id":7,"channelId":1}]}"#,
        ))
        .unwrap();
        assert!(server.wait_subscriptions(1, Duration::from_secs(10)));
        let m = pwm(4_002_450_975, 0);
        server.publish(m.clone());
        let WsMessage::Binary(b) = ws.read().unwrap() else {
            panic!("a binary frame")
        };
        let json = br#"{"board":"db09","device":"light_motor","kind":"pwm","pin":"A1.A","text":"db09 A1.A pwm 0","value":0}"#;
        let mut want = vec![0x01, 7, 0, 0, 0];
        want.extend_from_slice(&4_002_450_975u64.to_le_bytes());
        want.extend_from_slice(json);
        assert_eq!(b.as_ref(), want.as_slice());
        assert_eq!(m.data.to_string().as_bytes(), json);
        // Another topic: advertised as channel 2; a second client gets both channels.
        let call = Message {
            topic: CALLS_TOPIC.into(),
            schema: &crate::foxglove::CALL,
            log_time_ns: 5,
            data: json!({"text": "x"}),
        };
        server.publish(call);
        let ad = text(&mut ws);
        assert_eq!(ad["channels"][0]["id"], 2);
        assert_eq!(ad["channels"][0]["topic"], "/x10/calls");
        let mut second = connect(server.addr());
        assert_eq!(text(&mut second)["op"], "serverInfo");
        let ads = text(&mut second);
        let topics: Vec<&str> = ads["channels"]
            .as_array()
            .unwrap()
            .iter()
            .map(|c| c["topic"].as_str().unwrap())
            .collect();
        assert_eq!(topics, ["/x10/outputs/db09/A1_A/pwm", "/x10/calls"]);
        // Unsubscribed: nothing more; the next frame the first client gets is for its new
        // subscription on channel 2.
        ws.send(WsMessage::text(
            r#"{"op":"unsubscribe","subscriptionIds":[7]}"#,
        ))
        .unwrap();
        ws.send(WsMessage::text(
            r#"{"op":"subscribe","subscriptions":[{"id":8,"channelId":2}]}"#,
        ))
        .unwrap();
        assert!(server.wait_subscriptions(2, Duration::from_secs(10)));
        server.publish(pwm(6, 99));
        server.publish(Message {
            topic: CALLS_TOPIC.into(),
            schema: &crate::foxglove::CALL,
            log_time_ns: 9,
            data: json!({"text": "y"}),
        });
        let WsMessage::Binary(b) = ws.read().unwrap() else {
            panic!("a binary frame")
        };
        assert_eq!(
            b.as_ref(),
            message_frame(8, 9, br#"{"text":"y"}"#).as_slice()
        );
        let s = server.stats();
        assert_eq!(
            (s.clients, s.subscriptions, s.sent, s.dropped),
            (2, 2, 2, 0)
        );
    }

    #[test]
    fn a_client_without_the_foxglove_subprotocol_is_refused() {
        let server = LiveServer::start("127.0.0.1:0", "x10").unwrap();
        let stream = TcpStream::connect(server.addr()).unwrap();
        stream
            .set_read_timeout(Some(Duration::from_secs(10)))
            .unwrap();
        let req = format!("ws://{}", server.addr());
        assert!(tungstenite::client(req, stream).is_err());
        let (lock, cv) = &*server.stats;
        let guard = lock.lock().unwrap();
        let (s, _) = cv
            .wait_timeout_while(guard, Duration::from_secs(10), |s| s.refused == 0)
            .unwrap();
        assert_eq!((s.refused, s.clients), (1, 0));
    }
}
