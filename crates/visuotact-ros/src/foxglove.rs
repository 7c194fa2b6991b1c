//! Live to the Foxglove app: the same topics and messages as the bags ([`crate::topics`]),
//! served over the Foxglove WebSocket protocol by the official `foxglove` crate's server, so
//! that Foxglove's "Open connection → Foxglove WebSocket" shows the estimates, the contact,
//! the marker cloud, the health and (when asked) the frames live.
//!
//! Each topic is one channel with message encoding `cdr` and its `ros2msg` schema — what an
//! MCAP bag with the ROS 2 profile holds — so a panel reads the live run exactly as it reads a
//! bag; each message is logged with its stamp as the log time. Every topic a frame may have
//! (per sensor, for [`FoxgloveConfig::sensors`]) is made when the server starts, so a client
//! is told of all of them when it connects and can subscribe before the first frame (a topic
//! made while a client is connected is advertised to it before the server can take its
//! subscription: foxglove 0.30 answers one sent at once with "Unknown channel ID"). The
//! server listens on loopback (127.0.0.1:8765, Foxglove's
//! default) unless told another address; every client gets its own queue of
//! [`FoxgloveConfig::backlog`] messages, and a slow client loses its oldest messages, never
//! slowing the estimator.

use std::collections::HashMap;
use std::net::SocketAddr;
use std::sync::Arc;

use foxglove::{
    Context, PartialMetadata, RawChannel, Schema, WebSocketServer, WebSocketServerHandle,
};

use visuotact_pipeline::output::{FrameParts, FrameTarget, LiveSink, OutputConfig, OutputError};

use crate::msg::RosMessage;
use crate::topics::{declare_sensor_topics, typed_entry, write_frame, Declare, Publish};
use crate::RosError;

/// Where and how the live topics are served.
#[derive(Clone, Debug, PartialEq)]
pub struct FoxgloveConfig {
    /// Topics and frames.
    pub ros: OutputConfig,
    /// Address to listen on (port 0: any free port, see [`FoxglovePublisher::addr`]).
    pub addr: SocketAddr,
    /// Messages queued per client before its oldest are dropped.
    pub backlog: usize,
    /// The sensors of a run of several (topics under `NS/NAME`); empty for one sensor.
    pub sensors: Vec<String>,
}

impl FoxgloveConfig {
    /// Foxglove's default address on loopback.
    pub const DEFAULT_ADDR: &'static str = "127.0.0.1:8765";
}

impl Default for FoxgloveConfig {
    fn default() -> Self {
        Self {
            ros: OutputConfig {
                images: false,
                ..OutputConfig::default()
            },
            addr: SocketAddr::from(([127, 0, 0, 1], 8765)),
            backlog: 1024,
            sensors: Vec::new(),
        }
    }
}

/// A Foxglove WebSocket server with one raw channel per topic.
pub struct FoxglovePublisher {
    context: Arc<Context>,
    server: Option<WebSocketServerHandle>,
    addr: SocketAddr,
    channels: HashMap<String, (&'static str, Arc<RawChannel>)>,
    buf: Vec<u8>,
    /// Messages published.
    pub messages: u64,
}

impl FoxglovePublisher {
    /// Makes every topic's channel ([`declare_sensor_topics`]), then
    /// starts the server on `cfg.addr` (its own runtime threads).
    pub fn start(cfg: &FoxgloveConfig) -> Result<Self, RosError> {
        if cfg.backlog == 0 {
            return Err(RosError::Config(
                "Foxglove backlog must hold at least one message".into(),
            ));
        }
        let context = Context::new();
        let mut declared = Self {
            context: context.clone(),
            server: None,
            addr: cfg.addr,
            channels: HashMap::new(),
            buf: Vec::new(),
            messages: 0,
        };
        declare_sensor_topics(&mut declared, &cfg.ros, &cfg.sensors)?;
        let server = WebSocketServer::new()
            .name("visuotact")
            .context(&context)
            .bind(cfg.addr.ip().to_string(), cfg.addr.port())
            .message_backlog_size(cfg.backlog)
            .start_blocking()
            .map_err(|e| RosError::Config(format!("Foxglove server on {}: {e}", cfg.addr)))?;
        declared.addr = SocketAddr::new(cfg.addr.ip(), server.port());
        declared.server = Some(server);
        Ok(declared)
    }

    /// The address the server listens on (the port chosen when 0 was asked).
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// Clients connected now.
    pub fn clients(&self) -> usize {
        self.server
            .as_ref()
            .map_or(0, WebSocketServerHandle::client_count)
    }

    /// Stops the server, letting its clients' tasks end.
    pub fn stop(mut self) {
        self.shutdown();
    }

    fn shutdown(&mut self) {
        for (_, c) in self.channels.values() {
            c.close();
        }
        if let Some(s) = self.server.take() {
            s.stop().wait_blocking();
        }
    }

    fn channel<M: RosMessage>(&mut self, topic: &str) -> Result<&Arc<RawChannel>, RosError> {
        if !self.channels.contains_key(topic) {
            let schema = Schema::new(M::NAME, "ros2msg", M::DEFINITION.as_bytes());
            let channel = self
                .context
                .channel_builder(topic)
                .message_encoding("cdr")
                .schema(schema)
                .build_raw()
                .map_err(|e| RosError::Config(format!("Foxglove channel {topic}: {e}")))?;
            self.channels.insert(topic.to_string(), (M::NAME, channel));
        }
        typed_entry(&self.channels, topic, M::NAME)
    }
}

impl Declare for FoxglovePublisher {
    fn declare<M: RosMessage>(&mut self, topic: &str) -> Result<(), RosError> {
        self.channel::<M>(topic).map(|_| ())
    }
}

impl Drop for FoxglovePublisher {
    fn drop(&mut self) {
        self.shutdown();
    }
}

impl FrameTarget for FoxglovePublisher {
    fn write_frame(&mut self, cfg: &OutputConfig, f: FrameParts<'_>) -> Result<(), OutputError> {
        write_frame(self, cfg, f).map_err(OutputError::target)
    }
}

impl Publish for FoxglovePublisher {
    fn publish<M: RosMessage>(
        &mut self,
        topic: &str,
        stamp_ns: u64,
        msg: &M,
    ) -> Result<(), RosError> {
        let buf = msg.to_cdr_in(std::mem::take(&mut self.buf));
        let channel = self.channel::<M>(topic)?;
        channel.log_with_meta(&buf, PartialMetadata::with_log_time(stamp_ns));
        self.buf = buf;
        self.messages += 1;
        Ok(())
    }
}

/// A live run's estimates served to Foxglove: a [`FrameSink`](visuotact_pipeline::sink::FrameSink)
/// of the live runner, stamped on the wall clock like [`crate::McapSink`].
pub type FoxgloveSink = LiveSink<FoxglovePublisher>;

/// Starts the server; stamps count from now.
pub fn foxglove_sink(cfg: &FoxgloveConfig) -> Result<FoxgloveSink, RosError> {
    cfg.ros.validate()?;
    Ok(LiveSink::new(
        FoxglovePublisher::start(cfg)?,
        cfg.ros.clone(),
    )?)
}

/// Stops the server: the messages published, or the run's first error.
pub fn finish_foxglove(sink: FoxgloveSink) -> Result<u64, RosError> {
    sink.finish_with(|out| {
        let n = out.messages;
        out.stop();
        Ok(n)
    })
}
