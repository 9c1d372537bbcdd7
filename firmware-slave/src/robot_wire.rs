//! A robot [`Layout`] in the wire form of `protocol::robot`, both ways: the host cuts its
//! layout into parts with [`to_parts`]; the slave collects them in an [`Upload`] and rebuilds
//! the very same layout (the same bits) at the commit, after checking the fingerprint.

use protocol::robot::{fingerprint, AbsPart, CarriagePart, ExactPart, RobotHeader, WheelPart};
use robot_math::exact::{ExactParams, MAX_ENCODERS};
use robot_math::odometry::{AbsLayout, CarriageLayout, Layout};
use robot_math::wheel::Wheel;

/// A layout as upload parts: wheels and constants per encoder, and the header (with its
/// fingerprint).
pub fn to_parts(
    layout: &Layout,
) -> (
    [WheelPart; MAX_ENCODERS],
    [ExactPart; MAX_ENCODERS],
    RobotHeader,
) {
    let n = layout.encoders();
    let e = layout.exact();
    let (kx, ky, kth) = (e.kx(), e.ky(), e.kth());
    let wheels = core::array::from_fn(|j| {
        let w = layout.wheels()[j];
        WheelPart {
            index: j as u8,
            x_m: w.x,
            y_m: w.y,
            ux: w.ux,
            uy: w.uy,
            metres_per_count: layout.metres_per_count()[j],
        }
    });
    let exact = core::array::from_fn(|j| ExactPart {
        index: j as u8,
        kx: kx[j],
        ky: ky[j],
        kth: kth[j],
    });
    let mut header = RobotHeader {
        encoders: n as u8,
        carriage: layout.carriage().map(|c| CarriagePart {
            trail_m: c.trail_m,
            trail_q40: c.trail_q40,
        }),
        abs: layout.abs().map(|a| AbsPart {
            bits: a.bits,
            gray: a.gray,
            inverted: a.inverted,
        }),
        fingerprint: 0,
    };
    header.fingerprint = fingerprint(&wheels[..n], &exact[..n], &header);
    (wheels, exact, header)
}

/// The commands that upload `layout` to a slave, in order (each encoder's two parts, then the
/// commit), and the fingerprint the slave reports once it runs it. The host sends them through
/// the master (`HostToMaster::Slave`), on real boards and in the emulator alike.
pub fn upload_commands(
    layout: &Layout,
) -> (impl Iterator<Item = protocol::spi::SlaveCommand>, u32) {
    use protocol::spi::SlaveCommand;
    let (wheels, exact, header) = to_parts(layout);
    let parts = (0..layout.encoders()).flat_map(move |j| {
        [
            SlaveCommand::RobotWheel(wheels[j]),
            SlaveCommand::RobotExact(exact[j]),
        ]
    });
    (
        parts.chain(core::iter::once(SlaveCommand::RobotCommit(header))),
        header.fingerprint,
    )
}

/// The fingerprint of a layout (what the slave reports once it runs it).
pub fn layout_fingerprint(layout: &Layout) -> u32 {
    to_parts(layout).2.fingerprint
}

/// Why an upload was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UploadError {
    /// A part for encoder `index` is missing.
    Missing { index: u8 },
    /// The parts do not hash to the header's fingerprint (a lost or mixed-up part).
    Fingerprint { expected: u32, got: u32 },
    /// The parts do not make a layout the estimators accept.
    Layout,
}

/// The parts received so far.
#[derive(Clone, Copy, Debug, Default)]
pub struct Upload {
    wheels: [Option<WheelPart>; MAX_ENCODERS],
    exact: [Option<ExactPart>; MAX_ENCODERS],
}

impl Upload {
    pub fn wheel(&mut self, p: WheelPart) {
        if let Some(slot) = self.wheels.get_mut(p.index as usize) {
            *slot = Some(p);
        }
    }

    pub fn exact(&mut self, p: ExactPart) {
        if let Some(slot) = self.exact.get_mut(p.index as usize) {
            *slot = Some(p);
        }
    }

    /// Check the parts against `header` and build the layout into `into` (left as it was on
    /// `Err`); the parts are cleared either way.
    // Cold (an upload's end), and out of line for the image's size (388 B), as
    // `odometry_task`'s `wire_pose`.
    #[inline(never)]
    pub fn commit(&mut self, header: &RobotHeader, into: &mut Layout) -> Result<(), UploadError> {
        let built = self.build(header, into);
        *self = Upload::default();
        built
    }

    /// Write the layout the parts and `header` describe into `into` (left as it was on
    /// `Err`): built where it is kept, not returned and copied.
    fn build(&self, header: &RobotHeader, into: &mut Layout) -> Result<(), UploadError> {
        let n = (header.encoders as usize).min(MAX_ENCODERS);
        let mut wheels = [WheelPart::default(); MAX_ENCODERS];
        let mut exact = [ExactPart::default(); MAX_ENCODERS];
        for j in 0..n {
            wheels[j] = self.wheels[j].ok_or(UploadError::Missing { index: j as u8 })?;
            exact[j] = self.exact[j].ok_or(UploadError::Missing { index: j as u8 })?;
        }
        let got = fingerprint(&wheels[..n], &exact[..n], header);
        if got != header.fingerprint {
            return Err(UploadError::Fingerprint {
                expected: header.fingerprint,
                got,
            });
        }
        let params = ExactParams::from_raw(
            n,
            exact.map(|e| e.kx),
            exact.map(|e| e.ky),
            exact.map(|e| e.kth),
        )
        .map_err(|_| UploadError::Layout)?;
        into.set_parts(
            n as u8,
            wheels.map(|w| Wheel {
                x: w.x_m,
                y: w.y_m,
                ux: w.ux,
                uy: w.uy,
            }),
            wheels.map(|w| w.metres_per_count),
            params,
            header.carriage.map(|c| CarriageLayout {
                trail_m: c.trail_m,
                trail_q40: c.trail_q40,
            }),
            header.abs.map(|a| AbsLayout {
                bits: a.bits,
                gray: a.gray,
                inverted: a.inverted,
            }),
        )
        .map_err(|_| UploadError::Layout)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_layout_survives_the_wire_bit_for_bit() {
        let layout = Layout::SEED_004;
        let (w, e, h) = to_parts(&layout);
        let mut up = Upload::default();
        for j in 0..2 {
            // Through postcard, as the SPI frames carry them.
            let mut buf = [0u8; 64];
            let bytes = postcard::to_slice(&w[j], &mut buf).unwrap();
            up.wheel(postcard::from_bytes(bytes).unwrap());
            up.exact(e[j]);
        }
        let mut into = Layout::SEED_004;
        assert_eq!(up.commit(&h, &mut into), Ok(()));
        assert_eq!(into, layout);
        // A part missing, or a changed constant, is refused.
        let mut up = Upload::default();
        up.wheel(w[0]);
        up.exact(e[0]);
        up.exact(e[1]);
        assert_eq!(
            up.commit(&h, &mut into),
            Err(UploadError::Missing { index: 1 })
        );
        let mut up = Upload::default();
        up.wheel(w[0]);
        up.wheel(w[1]);
        up.exact(e[0]);
        up.exact(ExactPart {
            kx: e[1].kx + 1,
            ..e[1]
        });
        assert!(matches!(
            up.commit(&h, &mut into),
            Err(UploadError::Fingerprint { .. })
        ));
    }
}
