//! The live view (feature `live`): a Foxglove WebSocket server on a thread and a Tokio runtime of its
//! own, fed from the records the tick already hands over (the recorder's, through a bounded queue of
//! its own). The tick never encodes nor sends: it pushes plain records, and a record that does not
//! fit is dropped and counted. The publisher thread turns them into the recording's messages
//! ([`RecordEncoder`]) on the channels
//!
//! - `/foxglove/scene` (`foxglove.SceneUpdate`, at display rate: organs as triangle lists, tools,
//!   force arrows),
//! - `/palpa/tool/<tool>/feedback`, `/palpa/stats`, `/palpa/events` (`palpa.Feedback`, `palpa.Stats`,
//!   `palpa.Event` of `proto/palpa.proto`).
//!
//! The server is the Foxglove SDK's. Clients offer the subprotocol `foxglove.sdk.v1` (or `.v1.1`),
//! or the older name of the same protocol, `foxglove.websocket.v1`, which the SDK's server no longer
//! accepts: a small front on the public address reads each connection's upgrade request, renames an
//! offer of only the older name to the newer one (and the server's answer back), then passes the
//! bytes through untouched. A viewer that reads slowly or not at all fills its own buffers: the SDK
//! drops its oldest messages (and disconnects it if its control queue fills), so it never slows the
//! publisher, which never slows the tick.

use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

use foxglove::{ChannelBuilder, Context, PartialMetadata, RawChannel, Schema, WebSocketServer};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};

use super::DESCRIPTOR_SET;
use super::recorder::{
    MessageOut, Record, RecordEncoder, RecordError, RecordQueue, TOPIC_EVENTS, TOPIC_STATS,
    feedback_topic, largest_mesh_message,
};
use super::visual::{TOPIC_SCENE_UPDATE, scene_update_schema};
pub use crate::daemon::sink::LiveSummary;
use crate::ipc::payload::MeshHeaderV1;
use crate::world::World;

/// The current name of the Foxglove WebSocket protocol.
pub const SUBPROTOCOL: &str = "foxglove.sdk.v1";
/// The older name of the same protocol, still offered by older Foxglove apps and clients.
pub const SUBPROTOCOL_LEGACY: &str = "foxglove.websocket.v1";

/// Longest upgrade request or answer the front reads (bytes).
const MAX_HEAD_BYTES: usize = 16 * 1024;
/// Time a connection has to send its upgrade request.
const HEAD_TIMEOUT: Duration = Duration::from_secs(5);

/// Sizes of the live view's queue and server.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LiveSettings {
    /// Records the queue from the tick holds.
    pub queue_capacity: usize,
    /// Pooled mesh buffers.
    pub mesh_buffers: usize,
    /// Messages the server buffers per viewer before it drops the oldest.
    pub viewer_backlog: usize,
}

impl Default for LiveSettings {
    fn default() -> Self {
        Self {
            queue_capacity: 1 << 14,
            mesh_buffers: 16,
            viewer_backlog: 256,
        }
    }
}

/// The tick's side of the live view.
pub struct LiveView {
    records: RecordQueue,
    done: Arc<AtomicBool>,
    url: String,
    thread: Option<JoinHandle<LiveSummary>>,
}

/// `[HOST:]PORT` → a socket address to bind (host 127.0.0.1 when omitted; a name is resolved).
pub fn parse_address(text: &str) -> Result<SocketAddr, String> {
    use std::net::ToSocketAddrs;
    let text = text.trim();
    let with_host = if text.parse::<u16>().is_ok() {
        format!("127.0.0.1:{text}")
    } else {
        text.to_string()
    };
    with_host
        .to_socket_addrs()
        .map_err(|e| format!("--live {text}: expected [HOST:]PORT ({e})"))?
        .next()
        .ok_or_else(|| format!("--live {text}: the host has no address"))
}

/// The Foxglove WebSocket server of a live view, with its front on the public address, on a Tokio
/// runtime of its own (one worker thread). Stopped when dropped.
pub struct LiveServer {
    context: Arc<Context>,
    runtime: Option<tokio::runtime::Runtime>,
    server: Option<foxglove::WebSocketServerHandle>,
    address: SocketAddr,
    viewers: Arc<AtomicU64>,
}

/// Why the live view could not start.
#[derive(Debug, thiserror::Error)]
pub enum LiveError {
    /// Its I/O runtime (one worker thread) could not start.
    #[error("live view: cannot start its runtime: {0}")]
    Runtime(std::io::Error),
    /// The Foxglove SDK's WebSocket server could not start.
    #[error("live view: cannot start the WebSocket server: {0}")]
    Server(String),
    /// Viewers' address could not be listened on (in use, not this machine's).
    #[error("live view: cannot listen on {address}: {reason}")]
    Listen {
        /// The address asked for.
        address: SocketAddr,
        /// Why.
        reason: std::io::Error,
    },
    /// A channel of the session could not be made.
    #[error("live view: channel {topic}: {reason}")]
    Channel {
        /// The channel's topic.
        topic: String,
        /// The SDK's reason.
        reason: String,
    },
    /// The publisher's thread could not start.
    #[error("live view: cannot start its thread: {0}")]
    Thread(std::io::Error),
}

impl LiveServer {
    /// Starts the server, viewers connecting on `address` (port 0: a free one, see
    /// [`LiveServer::address`]); each viewer's backlog holds `viewer_backlog` messages.
    pub fn start(address: SocketAddr, viewer_backlog: usize) -> Result<Self, LiveError> {
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(1)
            .thread_name("palpa-live-io")
            .on_thread_start(keep_off_the_realtime_core)
            .enable_all()
            .build()
            .map_err(LiveError::Runtime)?;
        let context = Context::new();
        // The SDK's server on a loopback port of its own; viewers reach it through the front.
        let server = WebSocketServer::new()
            .name(concat!("palpa ", env!("CARGO_PKG_VERSION")))
            .context(&context)
            .tokio_runtime(runtime.handle())
            .bind("127.0.0.1", 0)
            .message_backlog_size(viewer_backlog.max(1))
            .start_blocking()
            .map_err(|e| LiveError::Server(e.to_string()))?;
        let inner = SocketAddr::from(([127, 0, 0, 1], server.port()));
        let listen = |reason| LiveError::Listen { address, reason };
        let listener = runtime
            .block_on(TcpListener::bind(address))
            .map_err(listen)?;
        let address = listener.local_addr().map_err(listen)?;
        let viewers = Arc::new(AtomicU64::new(0));
        runtime.spawn(accept_viewers(listener, inner, viewers.clone()));
        Ok(Self {
            context,
            runtime: Some(runtime),
            server: Some(server),
            address,
            viewers,
        })
    }

    /// Where viewers connect.
    pub fn address(&self) -> SocketAddr {
        self.address
    }

    /// The address to open in Foxglove.
    pub fn url(&self) -> String {
        viewer_url(self.address)
    }

    /// Viewers that connected so far.
    pub fn viewers(&self) -> u64 {
        self.viewers.load(Ordering::Relaxed)
    }

    /// The session's channels (see the module's documentation) for tools named `tools`.
    pub fn channels<'a>(
        &self,
        tools: impl IntoIterator<Item = &'a str>,
    ) -> Result<LiveChannels, LiveError> {
        LiveChannels::new(&self.context, tools)
    }
}

impl Drop for LiveServer {
    fn drop(&mut self) {
        if let Some(server) = self.server.take() {
            server.stop().detach_all();
        }
        if let Some(runtime) = self.runtime.take() {
            runtime.shutdown_timeout(Duration::from_secs(1));
        }
    }
}

/// The address a viewer opens for a server listening on `address`: `ws://HOST:PORT`, a wildcard host
/// shown as the loopback one.
pub fn viewer_url(address: SocketAddr) -> String {
    let mut shown = address;
    if shown.ip().is_unspecified() {
        shown.set_ip(std::net::Ipv4Addr::LOCALHOST.into());
    }
    format!("ws://{shown}")
}

/// `--live [HOST:]PORT` as a command-line value: the text, once [`parse_address`] accepts it (so a
/// bad address is a usage error before anything starts).
pub fn address_argument(text: &str) -> Result<String, String> {
    parse_address(text).map(|_| text.to_string())
}

impl LiveView {
    /// Starts the server on `address` (port 0: a free one, see [`LiveView::url`]) for a session
    /// of `world`, and the publisher thread.
    pub fn start(
        address: SocketAddr,
        world: &World,
        settings: LiveSettings,
    ) -> Result<Self, LiveError> {
        let server = LiveServer::start(address, settings.viewer_backlog)?;
        let channels = server.channels(world.tools.iter().map(|t| t.name.as_str()))?;
        let records = RecordQueue::new(
            settings.queue_capacity,
            settings.mesh_buffers,
            largest_mesh_message(world),
        );
        let done = Arc::new(AtomicBool::new(false));
        let url = server.url();
        let publisher = Publisher {
            records: records.share(),
            done: done.clone(),
            encoder: RecordEncoder::new(world),
            channels,
        };
        let thread = std::thread::Builder::new()
            .name("palpa-live".into())
            .spawn(move || {
                keep_off_the_realtime_core();
                let mut summary = publisher.run();
                summary.viewers = server.viewers();
                drop(server);
                summary
            })
            .map_err(LiveError::Thread)?;
        Ok(Self {
            records,
            done,
            url,
            thread: Some(thread),
        })
    }

    /// The address to open in Foxglove.
    pub fn url(&self) -> &str {
        &self.url
    }

    /// Hands a record over; never blocks. Returns false (and counts it) when it was dropped.
    pub fn push(&self, record: Record) -> bool {
        self.records.push(record, &|| false)
    }

    /// Copies a mesh message into a pooled buffer and hands it over; never blocks nor allocates.
    pub fn push_mesh(&self, header: &MeshHeaderV1, bytes: &[u8]) -> bool {
        self.records.push_mesh(header, bytes, &|| false)
    }

    /// Publishes what is queued, stops the server and returns what was done.
    pub fn finish(mut self) -> LiveSummary {
        self.close()
    }

    fn close(&mut self) -> LiveSummary {
        self.done.store(true, Ordering::Release);
        self.thread
            .take()
            .and_then(|t| t.join().ok())
            .unwrap_or_default()
    }
}

impl Drop for LiveView {
    fn drop(&mut self) {
        if self.thread.is_some() {
            self.close();
        }
    }
}

/// A live view's channels, by topic.
pub struct LiveChannels {
    channels: std::collections::BTreeMap<String, Arc<RawChannel>>,
    counts: std::collections::BTreeMap<String, u64>,
}

impl LiveChannels {
    fn new<'a>(
        context: &Arc<Context>,
        tools: impl IntoIterator<Item = &'a str>,
    ) -> Result<Self, LiveError> {
        let (name, encoding, data) = scene_update_schema();
        let mut wanted: Vec<(String, Schema)> =
            vec![(TOPIC_SCENE_UPDATE.into(), Schema::new(name, encoding, data))];
        let palpa =
            |message: &str| Schema::new(format!("palpa.{message}"), "protobuf", DESCRIPTOR_SET);
        for tool in tools {
            wanted.push((feedback_topic(tool), palpa("Feedback")));
        }
        wanted.push((TOPIC_STATS.into(), palpa("Stats")));
        wanted.push((TOPIC_EVENTS.into(), palpa("Event")));
        let mut channels = std::collections::BTreeMap::new();
        for (topic, schema) in wanted {
            let channel = ChannelBuilder::new(topic.clone())
                .context(context)
                .message_encoding("protobuf")
                .schema(schema)
                .build_raw()
                .map_err(|e| LiveError::Channel {
                    topic: topic.clone(),
                    reason: e.to_string(),
                })?;
            channels.insert(topic, channel);
        }
        Ok(Self {
            channels,
            counts: std::collections::BTreeMap::new(),
        })
    }

    /// Messages published per topic.
    pub fn counts(&self) -> &std::collections::BTreeMap<String, u64> {
        &self.counts
    }
}

impl MessageOut for LiveChannels {
    fn wants(&self, topic: &str) -> bool {
        self.channels.contains_key(topic)
    }

    /// Publishes `data` on `topic` (to every viewer subscribed to it); a topic the live view does not
    /// show is ignored.
    fn write(&mut self, topic: &str, _log_time: u64, data: &[u8]) -> Result<(), RecordError> {
        if let Some(channel) = self.channels.get(topic) {
            // Stamped with the time it is sent: a live view runs on the viewer's clock.
            channel.log_with_meta(data, PartialMetadata::default());
            *self.counts.entry(topic.to_string()).or_default() += 1;
        }
        Ok(())
    }
}

struct Publisher {
    records: RecordQueue,
    done: Arc<AtomicBool>,
    encoder: RecordEncoder,
    channels: LiveChannels,
}

impl Publisher {
    fn run(mut self) -> LiveSummary {
        let mut reported_drops = 0;
        let mut last_tick = 0;
        loop {
            let finishing = self.done.load(Ordering::Acquire);
            let mut busy = false;
            while let Some(record) = self.records.queue.pop() {
                busy = true;
                // Writing to the channels cannot fail; a record the encoder refuses is skipped.
                if let Ok(tick) = self.encoder.encode(
                    record,
                    &self.records.pool,
                    self.records.dropped(),
                    &mut self.channels,
                ) {
                    last_tick = tick;
                }
            }
            let dropped = self.records.dropped();
            if dropped > reported_drops {
                let _ = self.encoder.write_dropped(
                    &mut self.channels,
                    last_tick,
                    dropped - reported_drops,
                );
                reported_drops = dropped;
            }
            if finishing {
                break;
            }
            if !busy {
                std::thread::sleep(Duration::from_millis(1));
            }
        }
        LiveSummary {
            messages: self.channels.counts,
            dropped: self.records.dropped(),
            viewers: 0,
        }
    }
}

/// Keeps the calling thread off the core `palpa serve --rt` pins its loop to (the last one), where
/// there is another: the live view's work then never takes the loop's core.
fn keep_off_the_realtime_core() {
    // SAFETY: plain system calls on the calling thread with valid arguments.
    unsafe {
        let cores = libc::sysconf(libc::_SC_NPROCESSORS_ONLN).max(1) as usize;
        if cores < 2 {
            return;
        }
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        for core in 0..cores - 1 {
            libc::CPU_SET(core, &mut set);
        }
        // Best effort: a refusal leaves the thread where the scheduler puts it.
        let _ = libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &set);
    }
}

/// Accepts viewers on the public address, each passed to the SDK's server by [`pass_viewer`].
async fn accept_viewers(listener: TcpListener, inner: SocketAddr, viewers: Arc<AtomicU64>) {
    loop {
        let Ok((socket, _)) = listener.accept().await else {
            tokio::time::sleep(Duration::from_millis(10)).await;
            continue;
        };
        viewers.fetch_add(1, Ordering::Relaxed);
        tokio::spawn(async move {
            let _ = pass_viewer(socket, inner).await;
        });
    }
}

/// Reads an HTTP head (up to the blank line) into `buffer`; returns its length (what follows it,
/// if anything was read past it, stays in `buffer`).
async fn read_head(stream: &mut TcpStream, buffer: &mut Vec<u8>) -> std::io::Result<usize> {
    let mut chunk = [0u8; 2048];
    loop {
        if let Some(end) = buffer.windows(4).position(|w| w == b"\r\n\r\n") {
            return Ok(end + 4);
        }
        if buffer.len() > MAX_HEAD_BYTES {
            return Err(std::io::Error::new(
                std::io::ErrorKind::InvalidData,
                "HTTP head too long",
            ));
        }
        let read = stream.read(&mut chunk).await?;
        if read == 0 {
            return Err(std::io::ErrorKind::UnexpectedEof.into());
        }
        buffer.extend_from_slice(&chunk[..read]);
    }
}

/// Passes one viewer's connection to the server at `inner`, renaming the legacy subprotocol in the
/// upgrade (see the module's documentation), then copies bytes both ways until either side closes.
async fn pass_viewer(mut viewer: TcpStream, inner: SocketAddr) -> std::io::Result<()> {
    viewer.set_nodelay(true)?;
    let mut request = Vec::with_capacity(1024);
    let end = tokio::time::timeout(HEAD_TIMEOUT, read_head(&mut viewer, &mut request))
        .await
        .map_err(|_| std::io::Error::from(std::io::ErrorKind::TimedOut))??;
    let (head, legacy) = rename_offer(&request[..end]);
    let mut server = TcpStream::connect(inner).await?;
    server.set_nodelay(true)?;
    server.write_all(&head).await?;
    server.write_all(&request[end..]).await?;
    let mut answer = Vec::with_capacity(1024);
    let end = read_head(&mut server, &mut answer).await?;
    if legacy {
        viewer.write_all(&rename_answer(&answer[..end])).await?;
    } else {
        viewer.write_all(&answer[..end]).await?;
    }
    viewer.write_all(&answer[end..]).await?;
    tokio::io::copy_bidirectional(&mut viewer, &mut server).await?;
    Ok(())
}

/// Whether an HTTP head line is the `Sec-WebSocket-Protocol` header; its value if so.
fn protocol_header(line: &str) -> Option<&str> {
    let (name, value) = line.split_once(':')?;
    name.trim()
        .eq_ignore_ascii_case("sec-websocket-protocol")
        .then_some(value)
}

/// The upgrade request `head` with an offer of only [`SUBPROTOCOL_LEGACY`] (no `foxglove.sdk.*`)
/// renamed to [`SUBPROTOCOL`]; and whether it was. Any other head comes back unchanged.
pub fn rename_offer(head: &[u8]) -> (Vec<u8>, bool) {
    let Ok(text) = std::str::from_utf8(head) else {
        return (head.to_vec(), false);
    };
    let offered: Vec<&str> = text
        .split("\r\n")
        .filter_map(protocol_header)
        .flat_map(|v| v.split(','))
        .map(str::trim)
        .collect();
    let current = offered.iter().any(|p| p.starts_with("foxglove.sdk."));
    if current || !offered.contains(&SUBPROTOCOL_LEGACY) {
        return (head.to_vec(), false);
    }
    let renamed: Vec<String> = text
        .split("\r\n")
        .map(|line| match protocol_header(line) {
            Some(_) => format!("Sec-WebSocket-Protocol: {SUBPROTOCOL}"),
            None => line.to_string(),
        })
        .collect();
    (renamed.join("\r\n").into_bytes(), true)
}

/// The server's upgrade answer `head` with the protocol it chose named back [`SUBPROTOCOL_LEGACY`].
pub fn rename_answer(head: &[u8]) -> Vec<u8> {
    let Ok(text) = std::str::from_utf8(head) else {
        return head.to_vec();
    };
    text.split("\r\n")
        .map(|line| match protocol_header(line) {
            Some(value) if value.trim() == SUBPROTOCOL => {
                format!("Sec-WebSocket-Protocol: {SUBPROTOCOL_LEGACY}")
            }
            _ => line.to_string(),
        })
        .collect::<Vec<_>>()
        .join("\r\n")
        .into_bytes()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn request(protocols: &str) -> Vec<u8> {
        format!(
            "GET / HTTP/1.1\r\nHost: 127.0.0.1:8765\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n\
             Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\
             sec-websocket-protocol: {protocols}\r\n\r\n"
        )
        .into_bytes()
    }

    #[test]
    fn an_offer_of_only_the_legacy_name_is_renamed_and_the_answer_named_back() {
        let (head, legacy) = rename_offer(&request("foxglove.websocket.v1"));
        assert!(legacy);
        let text = String::from_utf8(head).unwrap();
        assert!(
            text.contains("\r\nSec-WebSocket-Protocol: foxglove.sdk.v1\r\n"),
            "{text}"
        );
        assert!(!text.contains("websocket.v1"), "{text}");
        assert!(
            text.ends_with("\r\n\r\n"),
            "the head's end is kept: {text:?}"
        );
        assert!(text.contains("Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"));
        let answer = b"HTTP/1.1 101 Switching Protocols\r\nupgrade: websocket\r\n\
            sec-websocket-protocol: foxglove.sdk.v1\r\n\r\n";
        let back = String::from_utf8(rename_answer(answer)).unwrap();
        assert!(
            back.contains("\r\nSec-WebSocket-Protocol: foxglove.websocket.v1\r\n"),
            "{back}"
        );
        assert!(back.ends_with("\r\n\r\n"));
    }

    #[test]
    fn an_offer_with_a_current_name_or_none_passes_unchanged() {
        for protocols in [
            "foxglove.sdk.v1",
            "foxglove.websocket.v1, foxglove.sdk.v1.1",
            "chat",
        ] {
            let original = request(protocols);
            let (head, legacy) = rename_offer(&original);
            assert!(!legacy, "{protocols}");
            assert_eq!(head, original, "{protocols}");
        }
    }

    #[test]
    fn addresses_take_a_port_alone_or_a_host_and_a_port() {
        assert_eq!(
            parse_address("8765").unwrap(),
            "127.0.0.1:8765".parse().unwrap()
        );
        assert_eq!(
            parse_address("0.0.0.0:9000").unwrap(),
            "0.0.0.0:9000".parse().unwrap()
        );
        assert!(parse_address("host.invalid:port").is_err());
        assert!(parse_address("70000").is_err());
    }
}
