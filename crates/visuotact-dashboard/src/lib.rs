//! The live dashboard: one page served from the binary (no CDN, no external files), estimates
//! pushed over a WebSocket, the latest frame as JPEG, and a re-zero button.
//!
//! Routes: `GET /` the page, `GET /ws` estimates (JSON text messages), `GET /frame.jpg` the
//! latest frame (`?after=N` waits, up to 2 s, for a frame newer than number N; the response's
//! `x-frame` header numbers it), `GET /info` image size, targets and markers, `POST /rezero`.
//! Several sensors of one run ([`Dashboard::start_several`]) each keep their own namespace:
//! `/info` lists them under `sensors`, every estimate carries its `sensor`, `/frame.jpg?sensor=NAME`
//! is that sensor's latest frame, and the page shows one sensor at a time with a choice of them.
//! The estimator
//! never waits for a client: each client has a small queue of its own, and a message that does
//! not fit (the client reads too slowly) is dropped for that client and counted.
//!
//! ## Modules and what each owns
//!
//! the live dashboard: one page embedded in the binary, estimates over a WebSocket (each client
//! its own small queue, drops counted), the latest frame as JPEG, a re-zero button; axum on a
//! tokio thread of its own; `DashboardError`

use std::collections::HashMap;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::extract::{RawQuery, State};
use axum::http::header;
use axum::response::{Html, IntoResponse, Response};
use axum::routing::{get, post};
use axum::{Json, Router};
use tokio::sync::mpsc;
use visuotact_image::RgbImage;
use visuotact_vision::calibration::SensorCalibration;

use visuotact_pipeline::live::MarkerView;

/// Why the dashboard could not start.
#[derive(Debug, thiserror::Error)]
pub enum DashboardError {
    /// The address does not parse.
    #[error("{addr:?}: expected HOST:PORT, e.g. 127.0.0.1:8080")]
    Address {
        /// The address given.
        addr: String,
    },
    /// The server's runtime could not start.
    #[error("cannot start the dashboard's runtime: {0}")]
    Runtime(std::io::Error),
    /// A dashboard of several sensors was given none.
    #[error("no sensor to show")]
    NoSensor,
    /// Nothing can listen there.
    #[error("{addr}: cannot listen: {source}")]
    Listen {
        /// The address.
        addr: SocketAddr,
        /// Why.
        source: std::io::Error,
    },
}

/// The page, embedded.
const PAGE: &str = include_str!("../assets/dashboard.html");

/// Messages a client may have waiting before new ones are dropped for it.
const CLIENT_QUEUE: usize = 8;

/// How long `/frame.jpg?after=N` waits for a newer frame before it answers with what it has.
const FRAME_WAIT: std::time::Duration = std::time::Duration::from_secs(2);

struct Shared {
    clients_tx: Mutex<Vec<mpsc::Sender<Arc<str>>>>,
    /// Each sensor's latest frame and its number (1, 2, … as published, over all sensors);
    /// a single sensor's under "".
    frame: Mutex<HashMap<String, (u64, Arc<RgbImage>)>>,
    /// The latest frame's number, for requests waiting on a newer one.
    frame_seq: tokio::sync::watch::Sender<u64>,
    rezero: AtomicBool,
    rezero_count: AtomicU64,
    rezero_applied: AtomicU64,
    clients: AtomicUsize,
    dropped: AtomicU64,
    info: serde_json::Value,
}

/// One sensor of a run of several, as the dashboard shows it.
pub struct DashboardSensor<'a> {
    /// The sensor's name (its namespace in every output).
    pub name: &'a str,
    /// Its calibration (image size, markers).
    pub calibration: &'a SensorCalibration,
    /// The targets its model estimates.
    pub targets: Vec<String>,
}

/// What `/info` says of one sensor.
fn sensor_info(cal: &SensorCalibration, targets: &[String]) -> serde_json::Value {
    serde_json::json!({
        "width": cal.image_width,
        "height": cal.image_height,
        "targets": targets,
        "markers": cal.markers.len(),
    })
}

/// A running dashboard server.
pub struct Dashboard {
    shared: Arc<Shared>,
    shutdown: Option<tokio::sync::oneshot::Sender<()>>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Dashboard {
    /// Serves on `addr` from a thread of its own.
    pub fn start(
        addr: &str,
        cal: &SensorCalibration,
        targets: Vec<String>,
    ) -> Result<Self, DashboardError> {
        Self::serve(addr, sensor_info(cal, &targets))
    }

    /// Serves the sensors of one run of several (`run --sensors`) on `addr`: `/info` gives
    /// the first sensor's fields and every sensor under `sensors` (with its `name`).
    pub fn start_several(
        addr: &str,
        sensors: &[DashboardSensor<'_>],
    ) -> Result<Self, DashboardError> {
        let first = sensors.first().ok_or(DashboardError::NoSensor)?;
        let mut info = sensor_info(first.calibration, &first.targets);
        let all: Vec<serde_json::Value> = sensors
            .iter()
            .map(|s| {
                let mut i = sensor_info(s.calibration, &s.targets);
                i["name"] = serde_json::Value::from(s.name);
                i
            })
            .collect();
        info["sensors"] = serde_json::Value::from(all);
        Self::serve(addr, info)
    }

    /// Serves on `addr` from a thread of its own, `/info` answering `info`.
    fn serve(addr: &str, info: serde_json::Value) -> Result<Self, DashboardError> {
        // Host names too (`localhost:8080`): the first address they resolve to.
        let sock: SocketAddr = std::net::ToSocketAddrs::to_socket_addrs(addr)
            .ok()
            .and_then(|mut a| a.next())
            .ok_or_else(|| DashboardError::Address {
                addr: addr.to_string(),
            })?;
        if !sock.ip().is_loopback() {
            visuotact_io::stderr_line(format_args!(
                "warning: the dashboard on {sock} is reachable from other machines"
            ));
        }
        let shared = Arc::new(Shared {
            clients_tx: Mutex::new(Vec::new()),
            frame: Mutex::new(HashMap::new()),
            frame_seq: tokio::sync::watch::Sender::new(0),
            rezero: AtomicBool::new(false),
            rezero_count: AtomicU64::new(0),
            rezero_applied: AtomicU64::new(0),
            clients: AtomicUsize::new(0),
            dropped: AtomicU64::new(0),
            info,
        });
        let rt = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(1)
            .enable_all()
            .build()
            .map_err(DashboardError::Runtime)?;
        let listen = |source| DashboardError::Listen { addr: sock, source };
        let listener = rt
            .block_on(tokio::net::TcpListener::bind(sock))
            .map_err(listen)?;
        let bound = listener.local_addr().map_err(listen)?;
        let app = Router::new()
            .route("/", get(|| async { Html(PAGE) }))
            .route("/ws", get(ws))
            .route("/frame.jpg", get(frame))
            .route("/info", get(info_route))
            .route("/rezero", post(rezero))
            .with_state(shared.clone());
        let (stop_tx, stop_rx) = tokio::sync::oneshot::channel::<()>();
        let thread = std::thread::spawn(move || {
            rt.block_on(async move {
                let serve = axum::serve(listener, app).with_graceful_shutdown(async {
                    let _ = stop_rx.await;
                });
                if let Err(e) = serve.await {
                    visuotact_io::stderr_line(format_args!("warning: dashboard: {e}"));
                }
            });
            rt.shutdown_background();
        });
        visuotact_io::stderr_line(format_args!("dashboard on http://{bound}/"));
        Ok(Self {
            shared,
            shutdown: Some(stop_tx),
            thread: Some(thread),
        })
    }

    /// Whether a WebSocket client is connected (the estimator then prepares drawing data).
    pub fn has_clients(&self) -> bool {
        self.shared.clients.load(Ordering::Relaxed) > 0
    }

    /// Whether the re-zero button was pressed since the last call.
    pub fn take_rezero(&self) -> bool {
        self.shared.rezero.swap(false, Ordering::Relaxed)
    }

    /// The estimator re-zeroed (the count goes out with the next estimates).
    pub fn rezero_applied(&self) {
        self.shared.rezero_applied.fetch_add(1, Ordering::Relaxed);
    }

    /// Messages lost by slow clients.
    pub fn dropped(&self) -> u64 {
        self.shared.dropped.load(Ordering::Relaxed)
    }

    /// Sends an estimate to every client and keeps the frame for `/frame.jpg` (under
    /// `sensor`'s name in a run of several). `estimate_json` is the estimate as already
    /// serialised for the other outputs.
    pub fn publish(
        &self,
        sensor: Option<&str>,
        estimate_json: &str,
        markers: Option<&[MarkerView]>,
        img: &Arc<RgbImage>,
    ) {
        if !self.has_clients() {
            return;
        }
        if let Ok(mut f) = self.shared.frame.lock() {
            let seq = *self.shared.frame_seq.borrow() + 1;
            let name = sensor.unwrap_or_default();
            // Each sensor's name is allocated once, not per frame.
            match f.get_mut(name) {
                Some(slot) => *slot = (seq, img.clone()),
                None => {
                    f.insert(name.to_string(), (seq, img.clone()));
                }
            }
            self.shared.frame_seq.send_replace(seq);
        }
        let markers = serde_json::to_string(&markers).unwrap_or_else(|_| "null".into());
        let text: Arc<str> = Arc::from(format!(
            "{{\"estimate\":{estimate_json},\"markers\":{markers},\"rezeros\":{}}}",
            self.shared.rezero_applied.load(Ordering::Relaxed)
        ));
        if let Ok(mut clients) = self.shared.clients_tx.lock() {
            clients.retain(|c| match c.try_send(text.clone()) {
                Ok(()) => true,
                Err(mpsc::error::TrySendError::Full(_)) => {
                    self.shared.dropped.fetch_add(1, Ordering::Relaxed);
                    true
                }
                // The client left.
                Err(mpsc::error::TrySendError::Closed(_)) => false,
            });
        }
    }

    /// Stops the server.
    pub fn stop(mut self) {
        if let Some(s) = self.shutdown.take() {
            let _ = s.send(());
        }
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// The dashboard as a live runner's sink: markers are drawn only while a client watches; the
/// re-zero button reaches the estimator.
impl visuotact_pipeline::sink::FrameSink for Dashboard {
    fn wants_markers(&self) -> bool {
        self.has_clients()
    }

    fn take_rezero(&mut self) -> bool {
        Dashboard::take_rezero(self)
    }

    fn rezero_applied(&mut self) {
        Dashboard::rezero_applied(self);
    }

    fn frame(
        &mut self,
        f: &visuotact_pipeline::sink::SinkFrame<'_>,
    ) -> Result<std::ops::ControlFlow<()>, visuotact_pipeline::sink::SinkError> {
        if let (Some(e), Some(json)) = (f.estimate, f.json) {
            self.publish(e.sensor.as_deref(), json, f.markers, f.image);
        }
        Ok(std::ops::ControlFlow::Continue(()))
    }
}

async fn ws(State(s): State<Arc<Shared>>, upgrade: WebSocketUpgrade) -> Response {
    upgrade.on_upgrade(move |socket| client(socket, s))
}

async fn client(mut socket: WebSocket, s: Arc<Shared>) {
    let (tx, mut rx) = mpsc::channel::<Arc<str>>(CLIENT_QUEUE);
    if let Ok(mut c) = s.clients_tx.lock() {
        c.push(tx);
    }
    s.clients.fetch_add(1, Ordering::Relaxed);
    loop {
        tokio::select! {
            m = rx.recv() => match m {
                Some(text) => {
                    if socket.send(Message::Text(text.as_ref().into())).await.is_err() {
                        break;
                    }
                }
                None => break,
            },
            incoming = socket.recv() => match incoming {
                Some(Ok(Message::Close(_))) | None | Some(Err(_)) => break,
                Some(Ok(_)) => {}
            },
        }
    }
    s.clients.fetch_sub(1, Ordering::Relaxed);
}

/// The value of `key` in a query `a=1&key=value`, if it has one.
fn query_value<'q>(query: Option<&'q str>, key: &str) -> Option<&'q str> {
    query?.split('&').find_map(|kv| {
        kv.split_once('=')
            .filter(|(k, _)| *k == key)
            .map(|(_, v)| v)
    })
}

/// The number N of a query `after=N`, if it has one.
fn after_from_query(query: Option<&str>) -> Option<u64> {
    query_value(query, "after")?.parse().ok()
}

/// The latest frame of `sensor` ("" for a single sensor) and its number.
fn latest(s: &Shared, sensor: &str) -> Option<(u64, Arc<RgbImage>)> {
    s.frame.lock().ok()?.get(sensor).cloned()
}

async fn frame(State(s): State<Arc<Shared>>, RawQuery(query): RawQuery) -> Response {
    let sensor = query_value(query.as_deref(), "sensor").unwrap_or_default();
    if let Some(after) = after_from_query(query.as_deref()) {
        // A client that has frame N asks for the next one: answer when it exists (the page
        // then shows each frame once instead of polling the same one again).
        let mut seq = s.frame_seq.subscribe();
        let newer = |_: &u64| latest(&s, sensor).is_some_and(|(k, _)| k > after);
        let _ = tokio::time::timeout(FRAME_WAIT, seq.wait_for(newer)).await;
    }
    let img = latest(&s, sensor);
    let Some((seq, img)) = img else {
        return (axum::http::StatusCode::NO_CONTENT, "").into_response();
    };
    let jpeg = tokio::task::spawn_blocking(move || {
        let mut out = Vec::new();
        let enc = image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, 80);
        image::ImageEncoder::write_image(
            enc,
            img.as_slice(),
            img.width() as u32,
            img.height() as u32,
            image::ExtendedColorType::Rgb8,
        )
        .map(|()| out)
    })
    .await;
    match jpeg {
        Ok(Ok(bytes)) => (
            [
                (header::CONTENT_TYPE, "image/jpeg".to_string()),
                (header::CACHE_CONTROL, "no-store".to_string()),
                (header::HeaderName::from_static("x-frame"), seq.to_string()),
            ],
            bytes,
        )
            .into_response(),
        _ => (
            axum::http::StatusCode::INTERNAL_SERVER_ERROR,
            "encoding failed",
        )
            .into_response(),
    }
}

async fn info_route(State(s): State<Arc<Shared>>) -> Json<serde_json::Value> {
    Json(s.info.clone())
}

async fn rezero(State(s): State<Arc<Shared>>) -> Json<serde_json::Value> {
    s.rezero.store(true, Ordering::Relaxed);
    let n = s.rezero_count.fetch_add(1, Ordering::Relaxed) + 1;
    Json(serde_json::json!({ "rezero": n }))
}

#[cfg(test)]
mod tests {
    use super::{after_from_query, query_value};

    #[test]
    fn the_frame_number_is_read_from_the_query() {
        assert_eq!(
            query_value(Some("after=3&sensor=left"), "sensor"),
            Some("left")
        );
        assert_eq!(query_value(Some("sensor=right"), "sensor"), Some("right"));
        assert_eq!(query_value(Some("after=3"), "sensor"), None);
        assert_eq!(after_from_query(Some("sensor=a&after=5")), Some(5));
        assert_eq!(after_from_query(Some("after=17")), Some(17));
        assert_eq!(after_from_query(Some("t=3&after=0")), Some(0));
        assert_eq!(after_from_query(Some("after=-1")), None);
        assert_eq!(after_from_query(Some("t=3")), None);
        assert_eq!(after_from_query(None), None);
    }
}
