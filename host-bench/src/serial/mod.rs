//! The link to real boards over serial (or to `host-bench virtual-board` over a
//! pseudo-terminal): framing and fault knobs ([`link`]), the handshake and board settings
//! ([`session`]), and the two bench jobs, [`play`] (tick streams into the slave, its poses
//! checked bit for bit against the host's, [`expected`]) and [`record`] (real encoders into a
//! tick stream). Their time is [`clock`]'s: the wall's, or a board model's.

pub mod adapter_latency;
pub mod clock;
pub mod drive;
pub mod expected;
pub mod link;
pub mod play;
pub mod played_stream;
pub mod record;
pub mod reports;
pub mod scorer;
pub mod session;
