//! The vocabulary both sites share, in one place:
//!
//! * [`joints`]: the joint and fingertip tables of the PR2 arm chain, the UR5 and the
//!   Shadow hand, in the one order every crate uses (fingers: ff, mf, rf, lf, th);
//! * [`topics`]: every topic of the system (key, message type, direction, rate, QoS
//!   class, deadline); `docs/topics.md` is generated from it;
//! * [`hardware`]: the hardware interfaces offered on the bus (which joints, which
//!   state and command topics, which node may command them);
//! * [`nodes`]: every node binary, its site, its machine and its config file.
//!
//! No I/O here: the transport (`teleop-bus`) implements the QoS classes, the nodes use
//! the names.

pub mod hardware;
pub mod joints;
pub mod nodes;
pub mod topics;

pub use hardware::{ArmInterface, HandInterface};
pub use nodes::{NodeSpec, Site};
pub use topics::{Direction, Publishers, QosClass, Topic, TopicSpec};
