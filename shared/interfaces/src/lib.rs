//! The vocabulary both sites share, in one place:
//!
//! * [`joints`]: the joint and fingertip tables of the PR2 arm chain, the UR5 and the
//!   Shadow hand, in the one order every crate uses (fingers: ff, mf, rf, lf, th);
//! * [`topics`]: every topic of the system (key, message type, direction, rate, QoS
//!   class, deadline); `docs/topics.md` is generated from it;
//! * [`hardware`]: the hardware interfaces offered on the bus (which joints, which
//!   state and command topics, which node may command them);
//! * [`nodes`]: every node binary, its site, its machine and its config file;
//! * [`calibration`]: the operator site's default calibrations (motion capture to
//!   UR5 base, marker to hand) and the config form of a rigid transform;
//! * [`timing`]: the measured, capped time step of every periodic core.
//!
//! No I/O here: the transport (`teleop-bus`) implements the QoS classes, the nodes use
//! the names.

pub mod calibration;
pub mod hardware;
pub mod joints;
pub mod nodes;
pub mod status;
pub mod timing;
pub mod topics;

pub use calibration::TransformConfig;
pub use hardware::{ArmInterface, HandInterface};
pub use nodes::{NodeSpec, Site};
pub use timing::StepTimer;
pub use topics::{Direction, Publishers, QosClass, Topic, TopicSpec};
