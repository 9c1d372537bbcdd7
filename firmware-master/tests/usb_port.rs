//! The `usb` image's host line, on the host: the board layer's CDC-ACM port (`usb_port.rs`,
//! what the image runs on the chip's USB driver) over a fake USB driver, with a scripted host
//! that enumerates it as Linux would. What a board is needed for (the chip's USB peripheral,
//! R10, a real host's driver) is not tested here; what the device says and how its port
//! carries the master's frames is.

use std::cell::RefCell;
use std::collections::{HashSet, VecDeque};
use std::future::poll_fn;
use std::rc::Rc;
use std::task::Poll;

use embassy_futures::block_on;
use embassy_futures::select::{select, Either};
use embassy_usb::driver::{
    Bus, ControlPipe, Direction, Driver, Endpoint, EndpointAddress, EndpointAllocError,
    EndpointError, EndpointIn, EndpointInfo, EndpointOut, EndpointType, Event, Unsupported,
};
use embedded_io_async::{Read, Write};
use firmware_master::ports::SerialRate;
use protocol::serial::{self, FrameDecoder, HostToMaster};

#[path = "../src/board/usb_port.rs"]
mod usb_port;

/// The USB host's side of the wire, as the fake driver's parts see it.
#[derive(Default)]
struct Wire {
    /// Control transfers to make: the setup packet and its OUT data stage.
    setups: VecDeque<([u8; 8], Vec<u8>)>,
    out_stage: Vec<u8>,
    /// What the device answered in IN data stages, and the transfers it finished or refused.
    control_in: Vec<u8>,
    finished: usize,
    refused: usize,
    powered: bool,
    reset: bool,
    enabled: HashSet<u8>,
    /// Bulk packets host -> device, and device -> host.
    bulk_out: VecDeque<Vec<u8>>,
    bulk_in: Vec<Vec<u8>>,
}

type Shared = Rc<RefCell<Wire>>;

struct FakeDriver {
    wire: Shared,
    next: u8,
}

struct Ep {
    info: EndpointInfo,
    wire: Shared,
}

struct FakeBus(Shared);

struct Control(Shared);

impl<'a> Driver<'a> for FakeDriver {
    type EndpointOut = Ep;
    type EndpointIn = Ep;
    type ControlPipe = Control;
    type Bus = FakeBus;

    fn alloc_endpoint_out(
        &mut self,
        ep_type: EndpointType,
        _addr: Option<EndpointAddress>,
        max_packet_size: u16,
        interval_ms: u8,
    ) -> Result<Ep, EndpointAllocError> {
        Ok(self.ep(Direction::Out, ep_type, max_packet_size, interval_ms))
    }

    fn alloc_endpoint_in(
        &mut self,
        ep_type: EndpointType,
        _addr: Option<EndpointAddress>,
        max_packet_size: u16,
        interval_ms: u8,
    ) -> Result<Ep, EndpointAllocError> {
        Ok(self.ep(Direction::In, ep_type, max_packet_size, interval_ms))
    }

    fn start(self, _control_max_packet_size: u16) -> (FakeBus, Control) {
        (FakeBus(self.wire.clone()), Control(self.wire))
    }
}

impl FakeDriver {
    /// The next endpoint number, each direction its own (as the chip's driver gives them).
    fn ep(&mut self, dir: Direction, ep_type: EndpointType, mps: u16, interval_ms: u8) -> Ep {
        self.next += 1;
        Ep {
            info: EndpointInfo {
                addr: EndpointAddress::from_parts(self.next as usize, dir),
                ep_type,
                max_packet_size: mps,
                interval_ms,
            },
            wire: self.wire.clone(),
        }
    }
}

impl Bus for FakeBus {
    async fn enable(&mut self) {}
    async fn disable(&mut self) {}
    async fn poll(&mut self) -> Event {
        poll_fn(|_| {
            let mut w = self.0.borrow_mut();
            if !w.powered {
                w.powered = true;
                Poll::Ready(Event::PowerDetected)
            } else if !w.reset {
                w.reset = true;
                Poll::Ready(Event::Reset)
            } else {
                Poll::Pending
            }
        })
        .await
    }
    fn endpoint_set_enabled(&mut self, ep: EndpointAddress, enabled: bool) {
        let mut w = self.0.borrow_mut();
        if enabled {
            w.enabled.insert(ep.into());
        } else {
            w.enabled.remove(&u8::from(ep));
        }
    }
    fn endpoint_set_stalled(&mut self, _ep: EndpointAddress, _stalled: bool) {}
    fn endpoint_is_stalled(&mut self, _ep: EndpointAddress) -> bool {
        false
    }
    async fn remote_wakeup(&mut self) -> Result<(), Unsupported> {
        Err(Unsupported)
    }
}

impl Endpoint for Ep {
    fn info(&self) -> &EndpointInfo {
        &self.info
    }
    async fn wait_enabled(&mut self) {
        let addr = u8::from(self.info.addr);
        poll_fn(|_| {
            if self.wire.borrow().enabled.contains(&addr) {
                Poll::Ready(())
            } else {
                Poll::Pending
            }
        })
        .await
    }
}

impl EndpointOut for Ep {
    async fn read(&mut self, buf: &mut [u8]) -> Result<usize, EndpointError> {
        poll_fn(|_| match self.wire.borrow_mut().bulk_out.pop_front() {
            Some(p) => {
                buf[..p.len()].copy_from_slice(&p);
                Poll::Ready(Ok(p.len()))
            }
            None => Poll::Pending,
        })
        .await
    }
}

impl EndpointIn for Ep {
    async fn write(&mut self, buf: &[u8]) -> Result<(), EndpointError> {
        if buf.len() > usize::from(self.info.max_packet_size) {
            return Err(EndpointError::BufferOverflow);
        }
        self.wire.borrow_mut().bulk_in.push(buf.to_vec());
        Ok(())
    }
}

impl ControlPipe for Control {
    fn max_packet_size(&self) -> usize {
        64
    }
    async fn setup(&mut self) -> [u8; 8] {
        poll_fn(|_| {
            let mut w = self.0.borrow_mut();
            match w.setups.pop_front() {
                Some((setup, data)) => {
                    w.out_stage = data;
                    Poll::Ready(setup)
                }
                None => Poll::Pending,
            }
        })
        .await
    }
    async fn data_out(
        &mut self,
        buf: &mut [u8],
        _first: bool,
        _last: bool,
    ) -> Result<usize, EndpointError> {
        let mut w = self.0.borrow_mut();
        let n = w.out_stage.len().min(buf.len());
        buf[..n].copy_from_slice(&w.out_stage[..n]);
        w.out_stage.drain(..n);
        Ok(n)
    }
    async fn data_in(
        &mut self,
        data: &[u8],
        _first: bool,
        last: bool,
    ) -> Result<(), EndpointError> {
        let mut w = self.0.borrow_mut();
        w.control_in.extend_from_slice(data);
        w.finished += usize::from(last);
        Ok(())
    }
    async fn accept(&mut self) {
        self.0.borrow_mut().finished += 1;
    }
    async fn reject(&mut self) {
        self.0.borrow_mut().refused += 1;
    }
    async fn accept_set_address(&mut self, _addr: u8) {
        self.0.borrow_mut().finished += 1;
    }
}

/// Pending until `cond` holds (the test's executor polls every future again and again).
async fn until(mut cond: impl FnMut() -> bool) {
    poll_fn(|_| {
        if cond() {
            Poll::Ready(())
        } else {
            Poll::Pending
        }
    })
    .await
}

/// One control transfer from the host: the answer of its IN data stage, if any.
async fn control(wire: &Shared, setup: [u8; 8], out: &[u8]) -> Vec<u8> {
    let before = {
        let mut w = wire.borrow_mut();
        w.control_in.clear();
        w.setups.push_back((setup, out.to_vec()));
        w.finished + w.refused
    };
    until(|| {
        let w = wire.borrow();
        w.finished + w.refused > before
    })
    .await;
    let w = wire.borrow();
    assert_eq!(w.refused, 0, "the device refused {setup:02x?}");
    w.control_in.clone()
}

const UID: [u8; 12] = [
    0x35, 0xFF, 0x6D, 0x06, 0x4E, 0x57, 0x36, 0x38, 0x35, 0x39, 0x13, 0x43,
];

#[test]
fn the_usb_port_says_who_it_is_and_carries_the_masters_frames() {
    let wire = Shared::default();
    let driver = FakeDriver {
        wire: wire.clone(),
        next: 0,
    };
    let statics = Box::leak(Box::default());
    let (mut device, mut tx, mut rx) = usb_port::build(driver, &UID, statics);
    let host = async {
        // The device descriptor: pid.codes' VID and PID, and a serial number string.
        let dev = control(&wire, [0x80, 6, 0, 1, 0, 0, 18, 0], &[]).await;
        assert_eq!(dev.len(), 18);
        let (vid, pid) = (
            u16::from_le_bytes([dev[8], dev[9]]),
            u16::from_le_bytes([dev[10], dev[11]]),
        );
        assert_eq!((vid, pid), (0x1209, 0x0001));
        let serial_index = dev[16];
        assert_ne!(serial_index, 0, "no serial number");
        // ...which is the chip's unique ID, as `host-bench probes` matches it.
        let s = control(&wire, [0x80, 6, serial_index, 3, 0x09, 0x04, 255, 0], &[]).await;
        let text: String =
            char::decode_utf16(s[2..].chunks(2).map(|c| u16::from_le_bytes([c[0], c[1]])))
                .map(Result::unwrap)
                .collect();
        assert_eq!(text, "35FF6D064E57363835391343");
        // The configuration: one CDC-ACM function (communication and data interfaces).
        let cfg = control(&wire, [0x80, 6, 0, 2, 0, 0, 255, 0], &[]).await;
        assert_eq!(cfg[4], 2, "interfaces in {cfg:02x?}");

        control(&wire, [0x00, 5, 7, 0, 0, 0, 0, 0], &[]).await; // SET_ADDRESS 7
        control(&wire, [0x00, 9, 1, 0, 0, 0, 0, 0], &[]).await; // SET_CONFIGURATION 1

        // Nobody has the port open (no DTR): what the master sends is dropped, not waited on.
        let mut frame = [0u8; serial::MAX_FRAME];
        let hello = HostToMaster::Hello {
            protocol_version: protocol::PROTOCOL_VERSION,
        };
        let bytes = serial::encode(&hello, &mut frame).unwrap().to_vec();
        assert_eq!(tx.write(&bytes).await, Ok(bytes.len()));
        assert!(wire.borrow().bulk_in.is_empty());

        // The host opens the port: SET_LINE_CODING (a rate, ignored), SET_CONTROL_LINE_STATE.
        let coding = 2_000_000u32.to_le_bytes();
        let line = [coding[0], coding[1], coding[2], coding[3], 0, 0, 8];
        control(&wire, [0x21, 0x20, 0, 0, 0, 0, 7, 0], &line).await;
        control(&wire, [0x21, 0x22, 1, 0, 0, 0, 0, 0], &[]).await; // DTR
        assert!(tx.set_baud(2_000_000), "a CDC-ACM port takes any rate");

        // Host -> master: a frame in packets of 5 bytes reaches the decoder whole.
        for p in bytes.chunks(5) {
            wire.borrow_mut().bulk_out.push_back(p.to_vec());
        }
        let mut decoder = FrameDecoder::new();
        let got = loop {
            let mut buf = [0u8; 3];
            let n = rx.read(&mut buf).await.unwrap();
            if let Some(m) = buf[..n]
                .iter()
                .find_map(|&b| decoder.push::<HostToMaster>(b))
            {
                break m.unwrap();
            }
        };
        assert_eq!(got, hello);

        // Master -> host: packets of 64 bytes, and a zero-length one after a full last one.
        let sizes = |w: &Shared| {
            w.borrow_mut()
                .bulk_in
                .drain(..)
                .map(|p| p.len())
                .collect::<Vec<_>>()
        };
        tx.write(&[0x55; 128]).await.unwrap();
        assert_eq!(sizes(&wire), [64, 64, 0]);
        tx.write(&[0x55; 70]).await.unwrap();
        assert_eq!(sizes(&wire), [64, 6]);
        tx.write(&bytes).await.unwrap();
        let packets = wire.borrow_mut().bulk_in.drain(..).collect::<Vec<_>>();
        assert_eq!(packets.concat(), bytes, "the frame as it went out");
    };
    match block_on(select(device.run(), host)) {
        Either::First(never) => match never {},
        Either::Second(()) => {}
    }
}
