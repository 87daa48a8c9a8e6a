//! The live server: a Foxglove WebSocket server (`foxglove.websocket.v1`, the SDK's own) fed by
//! a [`TeamWatch`] through a [`TeamBridge`], and optionally an MCAP file of the same channels.
//!
//! Promises: the server is listening when [`LiveServer::start`] returns (its port is known,
//! also when asked for port 0); channels are advertised to clients as the watcher first hears
//! of their ports, and only channels a client subscribed to are sent to it (the SDK's sinks);
//! [`LiveServer::stop`] closes the connections and finishes the MCAP file.

use std::path::Path;
use std::time::Duration as StdDuration;

use foxglove::{Context, FoxgloveError, McapWriterHandle, WebSocketServer, WebSocketServerHandle};

use crate::team_bridge::TeamBridge;
use crate::team_watch::{TeamWatch, WatchConfig};

/// A running server and the watcher that feeds it.
pub struct LiveServer {
    server: WebSocketServerHandle,
    mcap: Option<McapWriterHandle<std::io::BufWriter<std::fs::File>>>,
    bridge: TeamBridge,
    watch: TeamWatch,
}

/// Why the server could not start.
#[derive(Debug)]
pub enum LiveError {
    /// The watcher could not join the team's network (a bad URL, a bound port).
    Watch(String),
    /// The WebSocket server or the MCAP file could not be opened.
    Foxglove(FoxgloveError),
}

impl std::fmt::Display for LiveError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            LiveError::Watch(e) => write!(f, "{e}"),
            LiveError::Foxglove(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for LiveError {}

impl LiveServer {
    /// Join the team as `watch` says, listen on `host:port` (0: any free port), and, with
    /// `mcap`, also write every channel to that new file.
    pub fn start(watch: WatchConfig, host: &str, port: u16, mcap: Option<&Path>) -> Result<LiveServer, LiveError> {
        watch.check().map_err(LiveError::Watch)?;
        // The watcher and the server first: a bad URL or a taken port must not leave an empty
        // MCAP file behind. Channels are made later, as ports are heard, so the file misses none.
        let watch = TeamWatch::open(watch).map_err(|e| LiveError::Watch(e.to_string()))?;
        let ctx = Context::new();
        let server = WebSocketServer::new()
            .name("ayllu")
            .context(&ctx)
            .bind(host, port)
            .start_blocking()
            .map_err(LiveError::Foxglove)?;
        let mcap = match mcap.map(|path| ctx.mcap_writer().create_new_buffered_file(path)) {
            Some(Ok(handle)) => Some(handle),
            Some(Err(e)) => {
                server.stop().wait_blocking();
                return Err(LiveError::Foxglove(e));
            }
            None => None,
        };
        Ok(LiveServer { server, mcap, bridge: TeamBridge::new(&ctx), watch })
    }

    /// The port the server listens on.
    pub fn port(&self) -> u16 {
        self.server.port()
    }

    /// Clients connected now.
    pub fn clients(&self) -> usize {
        self.server.client_count()
    }

    /// The watcher (nodes heard, counts).
    pub fn watch(&self) -> &TeamWatch {
        &self.watch
    }

    /// Topics advertised so far.
    pub fn topics(&self) -> usize {
        self.bridge.topics()
    }

    /// Messages published so far.
    pub fn published(&self) -> u64 {
        self.bridge.published()
    }

    /// Watch and publish for `slice`.
    pub fn run_for(&mut self, slice: StdDuration) {
        self.watch.run_for(&mut self.bridge, slice);
    }

    /// Stop serving; finish the MCAP file.
    pub fn stop(self) -> Result<(), FoxgloveError> {
        let LiveServer { server, mcap, .. } = self;
        server.stop().wait_blocking();
        if let Some(m) = mcap {
            m.close()?;
        }
        Ok(())
    }
}
