//! Typed errors of the physical world.

/// What went wrong building or stepping the MuJoCo world.
#[derive(Debug, thiserror::Error)]
pub enum PhysicsError {
    /// MuJoCo's library could not be found or installed (build or run time).
    #[error(transparent)]
    Library(#[from] crate::library::NotFound),
    /// The robot description or the scene cannot be turned into MJCF.
    #[error("model: {0}")]
    Model(String),
    /// MuJoCo refused the generated MJCF (its compiler's message).
    #[error("MuJoCo could not compile the world: {0}")]
    Compile(String),
    /// A name the world needs is not in the compiled model.
    #[error("no {kind} named {name} in the MuJoCo model")]
    MissingName { kind: &'static str, name: String },
    /// A command or setting with a value that is not finite or out of range.
    #[error("invalid {what}: {why}")]
    Invalid { what: &'static str, why: String },
    /// The simulation diverged (MuJoCo's own warning, or a non-finite state).
    #[error("the simulation became unstable at t = {time_s:.3} s: {why}")]
    Unstable { time_s: f64, why: String },
}
