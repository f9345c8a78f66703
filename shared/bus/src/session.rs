//! [`Bus`]: a node's Zenoh session (two where hardware topics need their own), with typed [`Publisher`]s and [`Subscriber`]s.

use std::collections::VecDeque;
use std::marker::PhantomData;
use std::sync::atomic::{AtomicI64, AtomicU32, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

use teleop_interfaces::{QosClass, Topic, TopicSpec};
use teleop_msgs::Message;
use zenoh::Wait;
use zenoh::liveliness::LivelinessToken;
use zenoh::qos::{CongestionControl, Priority};

use crate::attachment::{ATTACHMENT_LEN, Attachment};
use crate::clock::{self, Clock};
use crate::config::BusConfig;
use crate::directory::{PublisherDirectory, PublisherInfo, gid_for_token};
use crate::guard::{GuardSettings, ReceiveGuard, Verdict};
use crate::keys::{self, EntityKind, GraphEntity};
use crate::stats::{Event, StatsSnapshot, TopicStats};

/// The Zenoh priority of a QoS class.
pub fn priority(qos: QosClass) -> Priority {
    match qos {
        QosClass::Control => Priority::RealTime,
        QosClass::State | QosClass::Receipt => Priority::InteractiveHigh,
        QosClass::Image => Priority::DataLow,
        QosClass::Diagnostics => Priority::Background,
    }
}

/// Which publishers may deliver samples to a subscriber.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub enum SourcePolicy {
    /// Any publisher (the receive guards still apply).
    #[default]
    Any,
    /// Only publishers that the node of this name announced (liveliness token) on this
    /// topic; everything else is dropped and counted as foreign. How a robot's
    /// hardware accepts commands from its own controller only.
    Node(String),
}

/// Errors of the bus.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum BusError {
    #[error("zenoh: {what}: {message}")]
    Zenoh { what: String, message: String },
    #[error(transparent)]
    Codec(#[from] teleop_msgs::CodecError),
    #[error(transparent)]
    Config(#[from] crate::config::ConfigError),
    #[error("subscriber on {topic}: the source policy names no node")]
    EmptySourceNode { topic: &'static str },
    #[error("invalid node name `{0}`: use letters, digits and `_`")]
    NodeName(String),
    #[error("bus clock: {0}")]
    Clock(String),
    #[error("topic type `{0}` is none of the message types")]
    UnknownType(String),
}

fn zerr(what: impl Into<String>) -> impl FnOnce(zenoh::Error) -> BusError {
    let what = what.into();
    move |e| BusError::Zenoh {
        what,
        message: e.to_string(),
    }
}

/// A node's connection to the system.
pub struct Bus {
    main: NodeSession,
    /// The session that carries the hardware topics when the node listens outside its
    /// hardware interfaces ([`crate::config::ZenohSettings::hardware_session`]).
    hardware: Option<NodeSession>,
    node_name: String,
    config: BusConfig,
    next_entity: AtomicU32,
    clock: Arc<dyn Clock>,
    directory: Arc<PublisherDirectory>,
}

/// One Zenoh session of a node, announced in the graph, feeding the node's publisher
/// directory.
struct NodeSession {
    session: zenoh::Session,
    zid: String,
    _directory_sub: zenoh::pubsub::Subscriber<()>,
    _node_token: LivelinessToken,
}

impl NodeSession {
    /// Opens session number `index` of the node (0: its own, 1: the hardware one).
    async fn open(
        index: u8,
        node_name: &str,
        domain_id: u32,
        zcfg: zenoh::Config,
        directory: &Arc<PublisherDirectory>,
    ) -> Result<Self, BusError> {
        let session = zenoh::open(zcfg).await.map_err(zerr("open session"))?;
        let zid = session.zid().to_string();
        let node = GraphEntity {
            domain_id,
            zid: zid.clone(),
            node_id: 0,
            entity_id: 0,
            kind: EntityKind::Node,
            namespace: String::new(),
            node_name: node_name.to_owned(),
            topic: None,
            dds_type: None,
            type_hash: None,
        };
        let token = session
            .liveliness()
            .declare_token(keys::liveliness_key(&node, ""))
            .await
            .map_err(zerr("declare node liveliness token"))?;
        let cb_directory = Arc::clone(directory);
        let directory_sub = session
            .liveliness()
            .declare_subscriber(format!(
                "{}/{}/*/*/*/MP/**",
                keys::LIVELINESS_PREFIX,
                domain_id
            ))
            .history(true)
            .callback(move |sample: zenoh::sample::Sample| {
                let alive = sample.kind() == zenoh::sample::SampleKind::Put;
                cb_directory.update_from(index, sample.key_expr().as_str(), alive);
            })
            .await
            .map_err(zerr("declare publisher directory subscriber"))?;
        Ok(Self {
            session,
            zid,
            _directory_sub: directory_sub,
            _node_token: token,
        })
    }

    async fn close(self) -> Result<(), BusError> {
        let NodeSession {
            session,
            _node_token,
            _directory_sub,
            ..
        } = self;
        drop(_node_token);
        drop(_directory_sub);
        session.close().await.map_err(zerr("close session"))
    }
}

impl std::fmt::Debug for Bus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Bus")
            .field("node_name", &self.node_name)
            .field("zid", &self.main.zid)
            .field(
                "hardware_zid",
                &self.hardware.as_ref().map(|h| h.zid.as_str()),
            )
            .field("domain_id", &self.config.domain_id)
            .finish()
    }
}

impl Bus {
    /// Opens a Zenoh session for node `node_name` on the system clock (or the run's
    /// simulated time, [`BusConfig::time`]) and announces the node's liveliness.
    ///
    /// # Errors
    /// [`BusError`] if the name is invalid, the configuration is refused or the session
    /// cannot open.
    pub async fn open(node_name: &str, config: &BusConfig) -> Result<Self, BusError> {
        let clock: Arc<dyn Clock> = match (config.time, &config.time_file) {
            (None, None) => clock::system(),
            (Some(t), None) => {
                Arc::new(clock::ScaledClock::new(t.origin_ns, t.scale).map_err(BusError::Clock)?)
            }
            (None, Some(path)) => {
                Arc::new(clock::PacedClock::open(path).map_err(|e| BusError::Clock(e.to_string()))?)
            }
            (Some(_), Some(path)) => {
                return Err(BusError::Clock(format!(
                    "a time scale and a clock file ({}) at once: give one",
                    path.display()
                )));
            }
        };
        Self::open_with_clock(node_name, config, clock).await
    }

    /// [`Bus::open`] with the node's clock: source timestamps of published samples and
    /// receive times of accepted ones come from `clock`.
    ///
    /// # Errors
    /// As [`Bus::open`].
    pub async fn open_with_clock(
        node_name: &str,
        config: &BusConfig,
        clock: Arc<dyn Clock>,
    ) -> Result<Self, BusError> {
        if node_name.is_empty()
            || !node_name
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '_')
        {
            return Err(BusError::NodeName(node_name.to_owned()));
        }
        let directory = PublisherDirectory::new();
        let zcfg = config.zenoh.to_zenoh()?;
        let hardware_cfg = config
            .zenoh
            .hardware_session()?
            .map(|z| z.to_zenoh())
            .transpose()?;
        let main = NodeSession::open(0, node_name, config.domain_id, zcfg, &directory).await?;
        let hardware = match hardware_cfg {
            Some(zcfg) => {
                let h = NodeSession::open(1, node_name, config.domain_id, zcfg, &directory).await?;
                tracing::info!(
                    node = node_name,
                    zid = h.zid,
                    "hardware topics on a second session, on the hardware interfaces alone \
                     (this node listens outside them)"
                );
                Some(h)
            }
            None => None,
        };
        Ok(Self {
            main,
            hardware,
            node_name: node_name.to_owned(),
            config: config.clone(),
            next_entity: AtomicU32::new(1),
            clock,
            directory,
        })
    }

    /// The node's clock.
    pub fn clock(&self) -> &Arc<dyn Clock> {
        &self.clock
    }

    /// Now on the node's clock, s since the Unix epoch.
    pub fn now_s(&self) -> f64 {
        self.clock.now_s()
    }

    /// The live publishers of this domain, by GID.
    pub fn directory(&self) -> &Arc<PublisherDirectory> {
        &self.directory
    }

    pub fn node_name(&self) -> &str {
        &self.node_name
    }
    pub fn zid(&self) -> &str {
        &self.main.zid
    }
    pub fn domain_id(&self) -> u32 {
        self.config.domain_id
    }
    pub fn config(&self) -> &BusConfig {
        &self.config
    }
    /// The underlying Zenoh session, for tools.
    pub fn session(&self) -> &zenoh::Session {
        &self.main.session
    }

    /// The session that carries `spec`'s topic: the hardware session for a hardware
    /// topic when the node has one, the node's session otherwise.
    fn session_for(&self, spec: &TopicSpec) -> &NodeSession {
        match &self.hardware {
            Some(h) if teleop_interfaces::topics::is_hardware_topic(spec.name) => h,
            _ => &self.main,
        }
    }

    /// The Zenoh id of the session carrying hardware topics, when it is not the
    /// node's own ([`Bus::zid`]).
    pub fn hardware_zid(&self) -> Option<&str> {
        self.hardware.as_ref().map(|h| h.zid.as_str())
    }

    fn entity(&self, kind: EntityKind, spec: &TopicSpec, dds_type: String) -> GraphEntity {
        GraphEntity {
            domain_id: self.config.domain_id,
            zid: self.session_for(spec).zid.clone(),
            node_id: 0,
            entity_id: self.next_entity.fetch_add(1, Ordering::Relaxed),
            kind,
            namespace: String::new(),
            node_name: self.node_name.clone(),
            topic: Some(spec.name.to_owned()),
            dds_type: Some(dds_type),
            type_hash: Some(spec.type_hash.to_owned()),
        }
    }

    /// Declares a publisher on `topic` with the topic's QoS.
    ///
    /// # Errors
    /// [`BusError::Zenoh`] if Zenoh refuses the declaration.
    pub async fn publisher<T: Message>(&self, topic: &Topic<T>) -> Result<Publisher<T>, BusError> {
        let spec = topic.spec;
        let (inner, key, gid, token) = self
            .declare_publisher(&spec, T::description().dds_type_name())
            .await?;
        Ok(Publisher {
            inner,
            spec,
            key,
            gid,
            sequence: AtomicI64::new(0),
            clock: Arc::clone(&self.clock),
            _token: token,
            _type: PhantomData,
        })
    }

    /// A publisher of `spec`'s topic that sends CDR bytes as they are (a replay, a
    /// bridge): each sample gets a fresh attachment (this publisher's GID, the next
    /// sequence number, now on the bus clock), so receivers check it like any other.
    ///
    /// # Errors
    /// [`BusError::Zenoh`] if Zenoh refuses the declaration; [`BusError::UnknownType`]
    /// if the topic's type is none of the message types.
    pub async fn raw_publisher(&self, spec: &TopicSpec) -> Result<RawPublisher, BusError> {
        let description = teleop_msgs::description_of(spec.type_name)
            .ok_or_else(|| BusError::UnknownType(spec.type_name.to_owned()))?;
        let (inner, key, gid, token) = self
            .declare_publisher(spec, description.dds_type_name())
            .await?;
        Ok(RawPublisher {
            inner,
            key,
            gid,
            sequence: AtomicI64::new(0),
            clock: Arc::clone(&self.clock),
            _token: token,
        })
    }

    /// Declares a publisher and its liveliness token; returns them with the key and
    /// the publisher's GID.
    async fn declare_publisher(
        &self,
        spec: &TopicSpec,
        dds_type: String,
    ) -> Result<
        (
            zenoh::pubsub::Publisher<'static>,
            String,
            [u8; 16],
            LivelinessToken,
        ),
        BusError,
    > {
        let key = keys::data_key_raw(self.config.domain_id, spec.name, &dds_type, spec.type_hash);
        let inner = self
            .session_for(spec)
            .session
            .declare_publisher(key.clone())
            .congestion_control(CongestionControl::Drop)
            .priority(priority(spec.qos))
            .express(spec.qos.express())
            .await
            .map_err(zerr(format!("declare publisher {key}")))?;
        let entity = self.entity(EntityKind::Publisher, spec, dds_type);
        let token_key = keys::liveliness_key(&entity, &keys::qos_string(true, spec.qos.depth()));
        let token = self
            .session_for(spec)
            .session
            .liveliness()
            .declare_token(token_key.clone())
            .await
            .map_err(zerr(format!("declare publisher token {key}")))?;
        Ok((inner, key, gid_for_token(&token_key), token))
    }

    /// Receive-guard settings for `spec` under this node's configuration.
    pub fn guard_settings(&self, spec: &TopicSpec) -> GuardSettings {
        let deadline_ms = self
            .config
            .deadlines_ms
            .get(spec.name)
            .copied()
            .or(spec.deadline_ms);
        GuardSettings {
            enforce_order: spec.qos.enforces_order(),
            deadline_ns: deadline_ms.map(|ms| ms.saturating_mul(1_000_000) as i64),
            clock_tolerance_ns: self.config.clock_tolerance_ms.saturating_mul(1_000_000) as i64,
        }
    }

    /// Declares a subscriber on `topic`. Samples are checked (attachment, order,
    /// deadline), decoded, counted, and queued with the topic's depth (newest only for
    /// control, state and image topics).
    ///
    /// # Errors
    /// [`BusError::Zenoh`] if Zenoh refuses the declaration.
    pub async fn subscriber<T: Message>(
        &self,
        topic: &Topic<T>,
    ) -> Result<Subscriber<T>, BusError> {
        self.subscriber_with(topic, self.guard_settings(&topic.spec), SourcePolicy::Any)
            .await
    }

    /// A subscriber that takes samples only from publishers announced by the node
    /// `node` on this topic ([`SourcePolicy::Node`]); samples from anyone else are
    /// dropped and counted (`<topic>.dropped_foreign`).
    ///
    /// # Errors
    /// [`BusError::Zenoh`] if Zenoh refuses the declaration,
    /// [`BusError::EmptySourceNode`] for an empty node name.
    pub async fn subscriber_from<T: Message>(
        &self,
        topic: &Topic<T>,
        node: &str,
    ) -> Result<Subscriber<T>, BusError> {
        if node.is_empty() {
            return Err(BusError::EmptySourceNode {
                topic: topic.spec.name,
            });
        }
        self.subscriber_with(
            topic,
            self.guard_settings(&topic.spec),
            SourcePolicy::Node(node.to_owned()),
        )
        .await
    }

    /// [`Bus::subscriber`] with explicit guard settings and source policy.
    ///
    /// # Errors
    /// [`BusError::Zenoh`] if Zenoh refuses the declaration.
    pub async fn subscriber_with<T: Message>(
        &self,
        topic: &Topic<T>,
        settings: GuardSettings,
        policy: SourcePolicy,
    ) -> Result<Subscriber<T>, BusError> {
        let spec = topic.spec;
        let key = keys::data_key::<T>(self.config.domain_id, spec.name);
        let shared = Arc::new(Shared::<T>::new(
            spec,
            settings,
            policy,
            Arc::clone(&self.directory),
        ));
        let cb_shared = Arc::clone(&shared);
        let cb_clock = Arc::clone(&self.clock);
        let inner = self
            .session_for(&spec)
            .session
            .declare_subscriber(key.clone())
            .callback(move |sample: zenoh::sample::Sample| {
                let payload = sample.payload().to_bytes();
                let att = sample.attachment().map(|a| a.to_bytes());
                cb_shared.on_sample(&payload, att.as_deref(), cb_clock.now_ns());
            })
            .await
            .map_err(zerr(format!("declare subscriber {key}")))?;
        let token = self
            .subscriber_token(&spec, T::description().dds_type_name(), &key)
            .await?;
        Ok(Subscriber {
            shared,
            _inner: inner,
            _token: token,
        })
    }

    /// Taps `spec`'s topic: every sample as it came off the wire goes to `sink` (called
    /// on Zenoh's thread: keep it short, hand the sample on), with no guard, no decoding
    /// and no copy kept. For recorders and bridges that store or forward the CDR bytes
    /// untouched. Announced in the graph as a subscriber, like any other.
    ///
    /// # Errors
    /// [`BusError::Zenoh`] if Zenoh refuses the declaration; [`BusError::UnknownType`]
    /// if the topic's type is none of the message types.
    pub async fn tap(
        &self,
        spec: &TopicSpec,
        sink: impl Fn(RawSample) + Send + Sync + 'static,
    ) -> Result<Tap, BusError> {
        let description = teleop_msgs::description_of(spec.type_name)
            .ok_or_else(|| BusError::UnknownType(spec.type_name.to_owned()))?;
        let dds_type = description.dds_type_name();
        let key = keys::data_key_raw(self.config.domain_id, spec.name, &dds_type, spec.type_hash);
        let clock = Arc::clone(&self.clock);
        let inner = self
            .session_for(spec)
            .session
            .declare_subscriber(key.clone())
            .callback(move |sample: zenoh::sample::Sample| {
                let attachment = sample
                    .attachment()
                    .and_then(|a| Attachment::from_bytes(&a.to_bytes()).ok());
                sink(RawSample {
                    payload: sample.payload().to_bytes().into_owned(),
                    attachment,
                    received_ns: clock.now_ns(),
                });
            })
            .await
            .map_err(zerr(format!("declare tap {key}")))?;
        let token = self.subscriber_token(spec, dds_type, &key).await?;
        Ok(Tap {
            _inner: inner,
            _token: token,
        })
    }

    /// Announces a subscriber of `spec`'s topic in the graph (its liveliness token).
    async fn subscriber_token(
        &self,
        spec: &TopicSpec,
        dds_type: String,
        key: &str,
    ) -> Result<LivelinessToken, BusError> {
        let entity = self.entity(EntityKind::Subscriber, spec, dds_type);
        self.session_for(spec)
            .session
            .liveliness()
            .declare_token(keys::liveliness_key(
                &entity,
                &keys::qos_string(true, spec.qos.depth()),
            ))
            .await
            .map_err(zerr(format!("declare subscriber token {key}")))
    }

    /// Every entity currently announced in this domain (nodes, publishers, subscribers,
    /// including those of ROS 2 nodes on rmw_zenoh).
    ///
    /// # Errors
    /// [`BusError::Zenoh`] if the liveliness query fails.
    pub async fn graph(&self, timeout: Duration) -> Result<Vec<GraphEntity>, BusError> {
        let replies = self
            .main
            .session
            .liveliness()
            .get(format!(
                "{}/{}/**",
                keys::LIVELINESS_PREFIX,
                self.config.domain_id
            ))
            .timeout(timeout)
            .await
            .map_err(zerr("liveliness query"))?;
        let mut out = Vec::new();
        while let Ok(reply) = replies.recv_async().await {
            if let Ok(sample) = reply.result()
                && let Some(e) = keys::parse_liveliness_key(sample.key_expr().as_str())
            {
                out.push(e);
            }
        }
        out.sort_by(|a, b| (&a.node_name, a.entity_id).cmp(&(&b.node_name, b.entity_id)));
        out.dedup();
        Ok(out)
    }

    /// Watches nodes appearing and vanishing in this domain.
    ///
    /// # Errors
    /// [`BusError::Zenoh`] if the liveliness subscriber cannot be declared.
    pub async fn watch_nodes(&self) -> Result<NodeWatch, BusError> {
        let state = Arc::new(WatchState::default());
        let cb_state = Arc::clone(&state);
        let inner = self
            .main
            .session
            .liveliness()
            .declare_subscriber(format!(
                "{}/{}/*/*/*/NN/**",
                keys::LIVELINESS_PREFIX,
                self.config.domain_id
            ))
            .history(true)
            .callback(move |sample: zenoh::sample::Sample| {
                let Some(e) = keys::parse_liveliness_key(sample.key_expr().as_str()) else {
                    return;
                };
                let alive = sample.kind() == zenoh::sample::SampleKind::Put;
                cb_state.update(&e.node_name, sample.key_expr().as_str(), alive);
            })
            .await
            .map_err(zerr("declare liveliness subscriber"))?;
        Ok(NodeWatch {
            state,
            _inner: inner,
        })
    }

    /// Closes the session (liveliness tokens vanish at once for the other nodes).
    ///
    /// # Errors
    /// [`BusError::Zenoh`] if closing fails.
    pub async fn close(self) -> Result<(), BusError> {
        let Bus { main, hardware, .. } = self;
        if let Some(h) = hardware {
            h.close().await?;
        }
        main.close().await
    }
}

/// A publisher of CDR bytes as they are ([`Bus::raw_publisher`]).
pub struct RawPublisher {
    inner: zenoh::pubsub::Publisher<'static>,
    key: String,
    gid: [u8; 16],
    sequence: AtomicI64,
    clock: Arc<dyn Clock>,
    _token: LivelinessToken,
}

impl std::fmt::Debug for RawPublisher {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RawPublisher")
            .field("key", &self.key)
            .finish()
    }
}

impl RawPublisher {
    /// Publishes `payload` (CDR, encapsulation header included) now, with the next
    /// sequence number (non-blocking: congestion drops the sample).
    ///
    /// # Errors
    /// Zenoh errors.
    pub fn put(&self, payload: Vec<u8>) -> Result<(), BusError> {
        let att = Attachment {
            sequence: self.sequence.fetch_add(1, Ordering::Relaxed) + 1,
            source_timestamp_ns: self.clock.now_ns(),
            gid: self.gid,
        };
        self.inner
            .put(payload)
            .attachment(att.to_bytes().to_vec())
            .wait()
            .map_err(zerr(format!("put on {}", self.key)))
    }
}

/// Typed publisher; stamps every sample with rmw_zenoh's attachment.
pub struct Publisher<T> {
    inner: zenoh::pubsub::Publisher<'static>,
    spec: TopicSpec,
    key: String,
    gid: [u8; 16],
    sequence: AtomicI64,
    clock: Arc<dyn Clock>,
    _token: LivelinessToken,
    _type: PhantomData<fn(T)>,
}

impl<T> std::fmt::Debug for Publisher<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Publisher").field("key", &self.key).finish()
    }
}

impl<T: Message> Publisher<T> {
    pub fn key(&self) -> &str {
        &self.key
    }
    pub fn spec(&self) -> &TopicSpec {
        &self.spec
    }
    pub fn gid(&self) -> [u8; 16] {
        self.gid
    }

    /// Now on the clock this publisher stamps its samples with (the node's), ns.
    pub fn now_ns(&self) -> i64 {
        self.clock.now_ns()
    }

    /// Publishes `msg` now, on the node's clock (non-blocking: congestion drops the
    /// sample).
    ///
    /// # Errors
    /// Encoding or Zenoh errors.
    pub fn put(&self, msg: &T) -> Result<(), BusError> {
        self.put_at(msg, self.clock.now_ns())
    }

    /// Publishes `msg` with an explicit source timestamp (ns since Unix epoch).
    ///
    /// # Errors
    /// Encoding or Zenoh errors.
    pub fn put_at(&self, msg: &T, source_timestamp_ns: i64) -> Result<(), BusError> {
        let payload = teleop_msgs::encode(msg)?;
        let att = Attachment {
            sequence: self.sequence.fetch_add(1, Ordering::Relaxed) + 1,
            source_timestamp_ns,
            gid: self.gid,
        };
        self.put_raw(payload, Some(att))
    }

    /// Publishes raw bytes with an optional attachment: for fault-injection tests and
    /// bridges. Receivers still check everything.
    ///
    /// # Errors
    /// Zenoh errors.
    pub fn put_raw(
        &self,
        payload: Vec<u8>,
        attachment: Option<Attachment>,
    ) -> Result<(), BusError> {
        let mut put = self.inner.put(payload);
        if let Some(a) = attachment {
            put = put.attachment(a.to_bytes().to_vec());
        }
        put.wait().map_err(zerr(format!("put on {}", self.key)))
    }

    /// Sequence number the next sample will carry.
    pub fn next_sequence(&self) -> i64 {
        self.sequence.load(Ordering::Relaxed) + 1
    }
}

/// A received, accepted sample with its metadata.
#[derive(Debug, Clone, PartialEq)]
pub struct Received<T> {
    pub msg: T,
    pub sequence: i64,
    pub source_timestamp_ns: i64,
    pub receive_timestamp_ns: i64,
    pub publisher_gid: [u8; 16],
}

impl<T> Received<T> {
    /// Receive time in seconds since the Unix epoch (receiver clock).
    pub fn receive_time_s(&self) -> f64 {
        self.receive_timestamp_ns as f64 * 1e-9
    }

    /// Receive time minus source time, ns.
    pub fn latency_ns(&self) -> i64 {
        self.receive_timestamp_ns - self.source_timestamp_ns
    }
}

/// A publisher a subscriber has heard from.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SeenPublisher {
    pub gid: [u8; 16],
    /// Receive time of its last sample with a valid attachment, ns (node clock).
    pub last_ns: i64,
    /// Whether its samples are refused (foreign to the source policy or the lock).
    pub refused: bool,
}

/// Most publishers a subscriber remembers having heard from (oldest forgotten first).
const MAX_SEEN: usize = 32;

struct Shared<T> {
    spec: TopicSpec,
    policy: SourcePolicy,
    directory: Arc<PublisherDirectory>,
    /// Only this publisher's samples are taken, when set.
    lock: Mutex<Option<[u8; 16]>>,
    seen: Mutex<Vec<SeenPublisher>>,
    queue: Mutex<VecDeque<Received<T>>>,
    ready: Condvar,
    notify: tokio::sync::Notify,
    /// Woken (`notify_one`) on every queued sample: see [`Subscriber::wake_on_sample`].
    wake: Mutex<Option<Arc<tokio::sync::Notify>>>,
    stats: TopicStats,
    guard: Mutex<ReceiveGuard>,
    log_limiter: Mutex<LogLimiter>,
}

/// Lets one warning per second through, and says how many were held back.
#[derive(Debug, Default)]
struct LogLimiter {
    last: Option<Instant>,
    suppressed: u64,
}

impl LogLimiter {
    fn allow(&mut self) -> Option<u64> {
        let now = Instant::now();
        match self.last {
            Some(t) if now.duration_since(t) < Duration::from_secs(1) => {
                self.suppressed += 1;
                None
            }
            _ => {
                self.last = Some(now);
                Some(std::mem::take(&mut self.suppressed))
            }
        }
    }
}

impl<T: Message> Shared<T> {
    fn new(
        spec: TopicSpec,
        settings: GuardSettings,
        policy: SourcePolicy,
        directory: Arc<PublisherDirectory>,
    ) -> Self {
        Self {
            spec,
            policy,
            directory,
            lock: Mutex::new(None),
            seen: Mutex::new(Vec::new()),
            queue: Mutex::new(VecDeque::with_capacity(spec.qos.depth())),
            ready: Condvar::new(),
            notify: tokio::sync::Notify::new(),
            wake: Mutex::new(None),
            stats: TopicStats::new(),
            guard: Mutex::new(ReceiveGuard::new(settings)),
            log_limiter: Mutex::new(LogLimiter::default()),
        }
    }

    fn warn(&self, what: std::fmt::Arguments<'_>) {
        let allowed = self.log_limiter.lock().ok().and_then(|mut l| l.allow());
        if let Some(suppressed) = allowed {
            tracing::warn!(topic = self.spec.name, suppressed, "{what}");
        }
    }

    fn on_sample(&self, payload: &[u8], attachment: Option<&[u8]>, now_ns: i64) {
        self.stats.count(Event::Received);
        let att = match attachment.map(Attachment::from_bytes) {
            Some(Ok(a)) => a,
            Some(Err(e)) => {
                self.stats.count(Event::BadAttachment);
                self.warn(format_args!("sample dropped: {e}"));
                return;
            }
            None => {
                self.stats.count(Event::BadAttachment);
                self.warn(format_args!(
                    "sample dropped: no attachment (expected {ATTACHMENT_LEN} bytes)"
                ));
                return;
            }
        };
        let allowed = self.source_allowed(&att.gid);
        self.note_publisher(att.gid, now_ns, !allowed);
        if !allowed {
            self.stats.count(Event::Foreign);
            self.warn(format_args!(
                "sample from a foreign publisher dropped ({})",
                self.describe(&att.gid)
            ));
            return;
        }
        let verdict = match self.guard.lock() {
            Ok(mut g) => g.check(&att, now_ns),
            Err(_) => return,
        };
        match verdict {
            Verdict::Accept => {}
            Verdict::OutOfOrder { sequence, last } => {
                self.stats.count(Event::OutOfOrder);
                tracing::debug!(
                    topic = self.spec.name,
                    sequence,
                    last,
                    "out-of-order sample dropped"
                );
                return;
            }
            Verdict::Stale { age_ns } => {
                self.stats.count(Event::Stale);
                self.warn(format_args!(
                    "stale sample dropped: {:.1} ms old",
                    age_ns as f64 / 1e6
                ));
                return;
            }
            Verdict::FromFuture { ahead_ns } => {
                self.stats.count(Event::FromFuture);
                self.warn(format_args!(
                    "sample dropped: source timestamp {:.1} ms in the future (clock offset?)",
                    ahead_ns as f64 / 1e6
                ));
                return;
            }
        }
        let msg = match teleop_msgs::decode::<T>(payload) {
            Ok(m) => m,
            Err(e) => {
                self.stats.count(Event::DecodeError);
                self.warn(format_args!("undecodable sample dropped: {e}"));
                return;
            }
        };
        self.stats.count(Event::Accepted);
        self.stats
            .record_latency_ns(now_ns - att.source_timestamp_ns);
        let received = Received {
            msg,
            sequence: att.sequence,
            source_timestamp_ns: att.source_timestamp_ns,
            receive_timestamp_ns: now_ns,
            publisher_gid: att.gid,
        };
        if let Ok(mut q) = self.queue.lock() {
            while q.len() >= self.spec.qos.depth().max(1) {
                q.pop_front();
                self.stats.count(Event::Overwritten);
            }
            q.push_back(received);
        }
        self.ready.notify_all();
        self.notify.notify_waiters();
        self.notify.notify_one();
        if let Ok(wake) = self.wake.lock()
            && let Some(w) = wake.as_ref()
        {
            w.notify_one();
        }
    }

    fn pop(&self) -> Option<Received<T>> {
        self.queue.lock().ok().and_then(|mut q| q.pop_front())
    }

    /// Whether the policy and the lock let a sample of publisher `gid` through.
    fn source_allowed(&self, gid: &[u8; 16]) -> bool {
        if let Ok(lock) = self.lock.lock()
            && let Some(locked) = *lock
            && locked != *gid
        {
            return false;
        }
        match &self.policy {
            SourcePolicy::Any => true,
            SourcePolicy::Node(node) => self.directory.lookup(gid).is_some_and(|p| {
                p.node_name == *node && p.topic.trim_start_matches('/') == self.spec.name
            }),
        }
    }

    fn note_publisher(&self, gid: [u8; 16], now_ns: i64, refused: bool) {
        let Ok(mut seen) = self.seen.lock() else {
            return;
        };
        if let Some(p) = seen.iter_mut().find(|p| p.gid == gid) {
            p.last_ns = now_ns;
            p.refused = refused;
            return;
        }
        if seen.len() >= MAX_SEEN
            && let Some(oldest) = seen
                .iter()
                .enumerate()
                .min_by_key(|(_, p)| p.last_ns)
                .map(|(i, _)| i)
        {
            seen.swap_remove(oldest);
        }
        seen.push(SeenPublisher {
            gid,
            last_ns: now_ns,
            refused,
        });
    }

    fn describe(&self, gid: &[u8; 16]) -> String {
        self.directory.lookup(gid).map_or_else(
            || "publisher announced by no node".to_owned(),
            |p| p.label(),
        )
    }
}

/// Typed subscriber. Holds the newest accepted sample(s) until taken.
/// One sample as it came off the wire ([`Bus::tap`]): the CDR payload untouched, its
/// attachment (`None` if absent or malformed), when it arrived (bus clock, ns).
#[derive(Debug, Clone, PartialEq)]
pub struct RawSample {
    pub payload: Vec<u8>,
    pub attachment: Option<Attachment>,
    pub received_ns: i64,
}

/// A raw subscription ([`Bus::tap`]); dropping it ends it.
pub struct Tap {
    _inner: zenoh::pubsub::Subscriber<()>,
    _token: LivelinessToken,
}

impl std::fmt::Debug for Tap {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Tap").finish_non_exhaustive()
    }
}

pub struct Subscriber<T> {
    shared: Arc<Shared<T>>,
    _inner: zenoh::pubsub::Subscriber<()>,
    _token: LivelinessToken,
}

impl<T> std::fmt::Debug for Subscriber<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Subscriber")
            .field("topic", &self.shared.spec.name)
            .finish()
    }
}

impl<T: Message> Subscriber<T> {
    pub fn spec(&self) -> &TopicSpec {
        &self.shared.spec
    }

    /// Takes the oldest queued sample (for depth-1 topics: the newest received), if any.
    pub fn try_recv(&self) -> Option<Received<T>> {
        self.shared.pop()
    }

    /// Whether a sample is queued (without taking it).
    pub fn has_sample(&self) -> bool {
        self.shared.queue.lock().is_ok_and(|q| !q.is_empty())
    }

    /// Waits for the next sample.
    pub async fn recv(&self) -> Received<T> {
        loop {
            let notified = self.shared.notify.notified();
            if let Some(r) = self.shared.pop() {
                return r;
            }
            notified.await;
        }
    }

    /// Waits up to `timeout` for the next sample.
    pub async fn recv_timeout(&self, timeout: Duration) -> Option<Received<T>> {
        tokio::time::timeout(timeout, self.recv()).await.ok()
    }

    /// Blocks the calling thread up to `timeout` for the next sample (for control loops
    /// on their own threads).
    pub fn recv_blocking(&self, timeout: Duration) -> Option<Received<T>> {
        let deadline = Instant::now() + timeout;
        let mut q = self.shared.queue.lock().ok()?;
        loop {
            if let Some(r) = q.pop_front() {
                return Some(r);
            }
            let left = deadline.checked_duration_since(Instant::now())?;
            q = self.shared.ready.wait_timeout(q, left).ok()?.0;
        }
    }

    pub fn stats(&self) -> StatsSnapshot {
        self.shared.stats.snapshot()
    }

    /// Wakes `wake` (`notify_one`: a wake-up with no one waiting is kept for the next
    /// wait) whenever a sample is queued, so that a node runner can act on a sample as
    /// it arrives instead of at its next period ([`None`]: no more wake-ups). Only
    /// accepted samples wake: foreign, stale or malformed ones do not.
    pub fn wake_on_sample(&self, wake: Option<Arc<tokio::sync::Notify>>) {
        if let Ok(mut w) = self.shared.wake.lock() {
            *w = wake;
        }
    }

    /// Takes samples only from publisher `gid` from now on (`None`: from every
    /// publisher the source policy allows). How a robot locks onto the one operator site
    /// that commands it; samples of other publishers are dropped and counted as
    /// foreign, never queued, so they cannot displace the locked publisher's newest
    /// sample.
    pub fn lock_source(&self, gid: Option<[u8; 16]>) {
        if let Ok(mut lock) = self.shared.lock.lock() {
            *lock = gid;
        }
    }

    /// Publishers heard from (valid attachment) at or after `since_ns` (node clock),
    /// refused ones included, most recent first.
    pub fn publishers_since(&self, since_ns: i64) -> Vec<SeenPublisher> {
        let mut out: Vec<SeenPublisher> = self
            .shared
            .seen
            .lock()
            .map(|s| {
                s.iter()
                    .filter(|p| p.last_ns >= since_ns)
                    .cloned()
                    .collect()
            })
            .unwrap_or_default();
        out.sort_by_key(|p| std::cmp::Reverse(p.last_ns));
        out
    }

    /// What the bus knows of publisher `gid` (node, session), if it announced itself.
    pub fn publisher_info(&self, gid: &[u8; 16]) -> Option<PublisherInfo> {
        self.shared.directory.lookup(gid)
    }

    /// The publishers of this topic that announce themselves now (live liveliness
    /// tokens), whether or not their samples reach this subscriber: one that is
    /// announced but never heard from is being dropped on the way (an access rule, a
    /// link that does not carry the topic).
    pub fn announced_publishers(&self) -> Vec<PublisherInfo> {
        let topic = format!("/{}", self.shared.spec.name.trim_start_matches('/'));
        self.shared.directory.publishers_of(&topic)
    }

    /// Named counters for node status reports.
    pub fn named_counters(&self) -> Vec<(String, u64)> {
        let prefix = self.shared.spec.name.rsplit('/').next().unwrap_or_default();
        self.shared.stats.named_counters(prefix)
    }
}

#[derive(Default)]
struct WatchState {
    /// node name -> liveliness keys currently alive with that name.
    alive: Mutex<std::collections::BTreeMap<String, std::collections::BTreeSet<String>>>,
    events: Mutex<VecDeque<NodeEvent>>,
    notify: tokio::sync::Notify,
}

impl WatchState {
    fn update(&self, name: &str, key: &str, alive: bool) {
        let event = {
            let Ok(mut map) = self.alive.lock() else {
                return;
            };
            if alive {
                let keys = map.entry(name.to_owned()).or_default();
                let first = keys.is_empty();
                keys.insert(key.to_owned());
                first.then(|| NodeEvent::Appeared(name.to_owned()))
            } else {
                let mut gone = false;
                if let Some(keys) = map.get_mut(name) {
                    keys.remove(key);
                    if keys.is_empty() {
                        map.remove(name);
                        gone = true;
                    }
                }
                gone.then(|| NodeEvent::Vanished(name.to_owned()))
            }
        };
        if let Some(e) = event {
            if let Ok(mut q) = self.events.lock() {
                if q.len() >= 1024 {
                    q.pop_front();
                }
                q.push_back(e);
            }
            self.notify.notify_waiters();
            self.notify.notify_one();
        }
    }
}

/// A node appearing or vanishing.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum NodeEvent {
    Appeared(String),
    Vanished(String),
}

/// Live view of the nodes of a domain (from their liveliness tokens).
pub struct NodeWatch {
    state: Arc<WatchState>,
    _inner: zenoh::pubsub::Subscriber<()>,
}

impl std::fmt::Debug for NodeWatch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("NodeWatch")
            .field("alive", &self.alive())
            .finish()
    }
}

impl NodeWatch {
    /// Names of the nodes alive now, sorted.
    pub fn alive(&self) -> Vec<String> {
        self.state
            .alive
            .lock()
            .map(|m| m.keys().cloned().collect())
            .unwrap_or_default()
    }

    pub fn is_alive(&self, name: &str) -> bool {
        self.state
            .alive
            .lock()
            .map(|m| m.contains_key(name))
            .unwrap_or(false)
    }

    /// Takes the next pending event, if any.
    pub fn try_event(&self) -> Option<NodeEvent> {
        self.state
            .events
            .lock()
            .ok()
            .and_then(|mut q| q.pop_front())
    }

    /// Waits up to `timeout` for the next event.
    pub async fn next_event(&self, timeout: Duration) -> Option<NodeEvent> {
        let wait = async {
            loop {
                let notified = self.state.notify.notified();
                if let Some(e) = self.try_event() {
                    return e;
                }
                notified.await;
            }
        };
        tokio::time::timeout(timeout, wait).await.ok()
    }
}
