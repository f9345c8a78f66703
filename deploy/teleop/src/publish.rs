//! `teleop topic pub`: publish samples of a topic from the command line, like
//! `ros2 topic pub`; with the fault-injection options, the bytes, sequence numbers,
//! timestamps and publisher GID an attacker or a broken node would send (every receiver
//! checks all of them: tests/security.rs, deploy/compose/check_security.sh).

use std::time::Duration;

use anyhow::{Context, bail};
use teleop_bus::{Attachment, Bus, BusConfig};
use teleop_interfaces::topics::{self, Topic, TopicSpec};
use teleop_msgs::description::{Arity, BaseType, MsgDescription};
use teleop_msgs::{
    CompressedImage, FingertipPressures, Header, Image, JointCommand, JointState, Message,
    NodeStatus, OperatorInput, PoseStamped, TFMessage,
};

#[derive(Debug, Clone, clap::Args)]
pub struct PubArgs {
    /// Topic, e.g. /teleop/operator_input.
    pub topic: String,
    /// The message as YAML or JSON (YAML writes NaN as .nan); fields left out are
    /// zero (or empty). Default: the all-zero message.
    pub message: Option<String>,
    /// Messages from a file instead, one JSON or YAML flow mapping per line, published
    /// in turn (and again from the top while -n or --duration-s asks for more).
    #[arg(long, conflicts_with = "message")]
    pub file: Option<std::path::PathBuf>,
    /// Publishing rate.
    #[arg(long, default_value_t = 10.0)]
    pub rate_hz: f64,
    /// How many samples (default 1, or unlimited with --duration-s).
    #[arg(long, short = 'n')]
    pub count: Option<u64>,
    /// Stop after this many seconds.
    #[arg(long)]
    pub duration_s: Option<f64>,
    /// The node name to publish as (default teleop_cli_<pid>); with access control the
    /// router takes it only from the identity of that name.
    #[arg(long)]
    pub node: Option<String>,
    /// Wait this long after opening the session before the first sample (discovery).
    #[arg(long, default_value_t = 0.5)]
    pub wait_s: f64,
    /// Set the messages' header stamp (if they have one) to the time of sending.
    #[arg(long)]
    pub stamp_now: bool,
    /// Fault injection: send these bytes (hex) as the payload instead of the message.
    #[arg(long, help_heading = "Fault injection")]
    pub raw_hex: Option<String>,
    /// Fault injection: no rmw_zenoh attachment.
    #[arg(long, help_heading = "Fault injection")]
    pub no_attachment: bool,
    /// Fault injection: the first sample's sequence number (then counting up).
    #[arg(long, help_heading = "Fault injection")]
    pub first_sequence: Option<i64>,
    /// Fault injection: shift the source timestamp by this much (ms; > 0 is the future).
    #[arg(long, help_heading = "Fault injection", allow_hyphen_values = true)]
    pub stamp_offset_ms: Option<f64>,
    /// Fault injection: claim this publisher GID (32 hex digits), e.g. another node's.
    #[arg(long, help_heading = "Fault injection")]
    pub gid: Option<String>,
}

/// Parses hex digits (spaces allowed) into bytes.
pub fn parse_hex(text: &str) -> anyhow::Result<Vec<u8>> {
    let digits: Vec<u8> = text.bytes().filter(|b| !b.is_ascii_whitespace()).collect();
    if !digits.len().is_multiple_of(2) {
        bail!("hex text has an odd number of digits ({})", digits.len());
    }
    digits
        .chunks(2)
        .map(|pair| {
            let s = std::str::from_utf8(pair).unwrap_or("??");
            u8::from_str_radix(s, 16).with_context(|| format!("`{s}` is not a hex byte"))
        })
        .collect()
}

/// The all-zero value of a message type (empty strings and sequences), as YAML.
fn zero_value(desc: &'static MsgDescription) -> serde_yaml::Value {
    use serde_yaml::Value;
    let mut map = serde_yaml::Mapping::new();
    for f in desc.fields {
        let one = match f.base {
            BaseType::Nested(get) => zero_value(get()),
            BaseType::Bool => Value::Bool(false),
            BaseType::String => Value::String(String::new()),
            BaseType::Float32 | BaseType::Float64 => Value::from(0.0),
            _ => Value::from(0),
        };
        let v = match f.arity {
            Arity::Single => one,
            Arity::Array(n) => Value::Sequence(vec![one; n as usize]),
            Arity::Sequence => Value::Sequence(Vec::new()),
        };
        map.insert(Value::String(f.name.to_owned()), v);
    }
    serde_yaml::Value::Mapping(map)
}

/// `patch` laid over `base`, mapping by mapping.
fn merge(base: &mut serde_yaml::Value, patch: serde_yaml::Value) {
    match (base, patch) {
        (serde_yaml::Value::Mapping(b), serde_yaml::Value::Mapping(p)) => {
            for (k, v) in p {
                match b.get_mut(&k) {
                    Some(slot) => merge(slot, v),
                    None => {
                        b.insert(k, v);
                    }
                }
            }
        }
        (slot, v) => *slot = v,
    }
}

/// Messages of type `T` from YAML/JSON texts; fields left out are zero.
fn parse_messages<T: Message>(texts: &[String]) -> anyhow::Result<Vec<T>> {
    texts
        .iter()
        .enumerate()
        .map(|(i, t)| {
            let what = || format!("message {} is not a {}: {t}", i + 1, T::TYPE_NAME);
            let patch: serde_yaml::Value = serde_yaml::from_str(t).with_context(what)?;
            let mut v = zero_value(T::description());
            merge(&mut v, patch);
            serde_yaml::from_value::<T>(v).with_context(what)
        })
        .collect()
}

/// Sets the header stamp of `msg` to `ns` (types with a header).
fn stamp<T: Message>(msg: &mut T, ns: i64) -> anyhow::Result<()> {
    let mut v = serde_yaml::to_value(&*msg)?;
    if let Some(h) = v.get_mut("header").and_then(|h| h.get_mut("stamp")) {
        let t = teleop_msgs::Time::from_nanos(ns);
        *h = serde_yaml::to_value(t)?;
        *msg = serde_yaml::from_value(v)?;
    }
    Ok(())
}

async fn publish_typed<T: Message>(
    bus: &Bus,
    spec: &TopicSpec,
    args: &PubArgs,
    texts: &[String],
) -> anyhow::Result<u64> {
    let topic = Topic::<T>::from_spec(spec).context("topic type mismatch")?;
    let mut msgs: Vec<T> = if texts.is_empty() {
        parse_messages(&["{}".to_owned()])?
    } else {
        parse_messages(texts)?
    };
    let raw = args.raw_hex.as_deref().map(parse_hex).transpose()?;
    let gid = match &args.gid {
        Some(h) => {
            let b = parse_hex(h)?;
            <[u8; 16]>::try_from(b.as_slice()).map_err(|_| {
                anyhow::anyhow!("--gid needs 16 bytes (32 hex digits), got {}", b.len())
            })?
        }
        None => [0; 16],
    };
    let publisher = bus.publisher(&topic).await?;
    let gid = if args.gid.is_some() {
        gid
    } else {
        publisher.gid()
    };
    tokio::time::sleep(Duration::from_secs_f64(args.wait_s.clamp(0.0, 30.0))).await;
    let count = args.count.unwrap_or(if args.duration_s.is_some() {
        u64::MAX
    } else {
        1
    });
    let until = args
        .duration_s
        .map(|s| tokio::time::Instant::now() + Duration::from_secs_f64(s));
    let mut ticker = tokio::time::interval(Duration::from_secs_f64(1.0 / args.rate_hz));
    let mut sequence = args.first_sequence.unwrap_or(1);
    let offset_ns = args.stamp_offset_ms.map_or(0, |ms| (ms * 1e6) as i64);
    let mut sent = 0u64;
    while sent < count && until.is_none_or(|u| tokio::time::Instant::now() < u) {
        ticker.tick().await;
        let now = bus.clock().now_ns();
        let i = (sent % msgs.len() as u64) as usize;
        if args.stamp_now {
            stamp(&mut msgs[i], now)?;
        }
        let payload = match &raw {
            Some(bytes) => bytes.clone(),
            None => teleop_msgs::encode(&msgs[i])?,
        };
        let attachment = (!args.no_attachment).then_some(Attachment {
            sequence,
            source_timestamp_ns: now + offset_ns,
            gid,
        });
        publisher.put_raw(payload, attachment)?;
        sequence += 1;
        sent += 1;
    }
    // Let the last samples leave before the session closes.
    tokio::time::sleep(Duration::from_millis(200)).await;
    Ok(sent)
}

pub async fn run(cfg: &BusConfig, args: &PubArgs) -> anyhow::Result<()> {
    if !(args.rate_hz.is_finite() && args.rate_hz > 0.0 && args.rate_hz <= 10_000.0) {
        bail!("--rate-hz must be in (0, 10000], got {}", args.rate_hz);
    }
    if let Some(s) = args.duration_s
        && !(s.is_finite() && s > 0.0)
    {
        bail!("--duration-s must be a positive number, got {s}");
    }
    let spec = topics::find(&args.topic)
        .with_context(|| format!("unknown topic `{}` (teleop topics lists them)", args.topic))?;
    let texts: Vec<String> = match (&args.message, &args.file) {
        (Some(m), _) => vec![m.clone()],
        (None, Some(path)) => std::fs::read_to_string(path)
            .with_context(|| format!("reading {}", path.display()))?
            .lines()
            .map(str::trim)
            .filter(|l| !l.is_empty() && !l.starts_with('#'))
            .map(str::to_owned)
            .collect(),
        (None, None) => Vec::new(),
    };
    let name = args
        .node
        .clone()
        .unwrap_or_else(|| format!("teleop_cli_{}", std::process::id()));
    let bus = Bus::open(&name, cfg)
        .await
        .context("opening the Zenoh session")?;
    let sent = match spec.type_name {
        t if t == PoseStamped::TYPE_NAME => {
            publish_typed::<PoseStamped>(&bus, spec, args, &texts).await
        }
        t if t == JointState::TYPE_NAME => {
            publish_typed::<JointState>(&bus, spec, args, &texts).await
        }
        t if t == OperatorInput::TYPE_NAME => {
            publish_typed::<OperatorInput>(&bus, spec, args, &texts).await
        }
        t if t == FingertipPressures::TYPE_NAME => {
            publish_typed::<FingertipPressures>(&bus, spec, args, &texts).await
        }
        t if t == Image::TYPE_NAME => publish_typed::<Image>(&bus, spec, args, &texts).await,
        t if t == CompressedImage::TYPE_NAME => {
            publish_typed::<CompressedImage>(&bus, spec, args, &texts).await
        }
        t if t == JointCommand::TYPE_NAME => {
            publish_typed::<JointCommand>(&bus, spec, args, &texts).await
        }
        t if t == NodeStatus::TYPE_NAME => {
            publish_typed::<NodeStatus>(&bus, spec, args, &texts).await
        }
        t if t == Header::TYPE_NAME => publish_typed::<Header>(&bus, spec, args, &texts).await,
        t if t == TFMessage::TYPE_NAME => {
            publish_typed::<TFMessage>(&bus, spec, args, &texts).await
        }
        other => bail!("no encoder for type {other}"),
    }?;
    eprintln!("published {sent} samples on /{} as {name}", spec.name);
    bus.close().await?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hex_and_messages_parse_or_name_the_fault() {
        assert_eq!(parse_hex("de ad BE ef").unwrap(), [0xde, 0xad, 0xbe, 0xef]);
        assert!(parse_hex("abc").unwrap_err().to_string().contains("odd"));
        assert!(parse_hex("zz").unwrap_err().to_string().contains("zz"));
        let m: Vec<OperatorInput> =
            parse_messages(&["{clutch: true, enable: true, motion_scale: 1.0}".into()]).unwrap();
        assert!(m[0].clutch && m[0].enable);
        let p: Vec<PoseStamped> =
            parse_messages(&["{pose: {position: {x: .nan}}}".into()]).unwrap();
        assert!(p[0].pose.position.x.is_nan());
        let e = parse_messages::<OperatorInput>(&["{clutch: 3}".into()]).unwrap_err();
        assert!(e.to_string().contains("message 1"), "{e}");
        let mut p = PoseStamped::default();
        stamp(&mut p, 1_500_000_000_250_000_000).unwrap();
        assert_eq!(p.header.stamp.sec, 1_500_000_000);
        assert_eq!(p.header.stamp.nanosec, 250_000_000);
    }
}
