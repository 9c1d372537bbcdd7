//! The master's async tasks: thin loops between the ports and the [`Controller`](crate::controller::Controller).
//!
//! [`start`] first, then each task is a task of its own in the executor: on the board
//! (`main.rs`) as in an emulation (host-bench's `spawn_master`). A wake-up then polls only the
//! task it is for. Joined into one future, as they were, every timer, DMA and serial wake-up
//! polled all four: a sixth of the master's instructions while it relayed a play, and the
//! serial reader, polled by everyone else's wake-ups, hid that the chip model never raised
//! USART1's interrupt.

use embassy_futures::select::{select, select3, Either, Either3};
use embassy_time::{Duration, Instant, Ticker, Timer};
use embedded_io_async::{Read, Write};
use protocol::serial::{self, FrameDecoder, HostToMaster, MasterToHost};
use protocol::spi::{self, SlaveFrame, SPI_FRAME_LEN};

use crate::controller::Drive;
use crate::ports::{MotorDrivers, MotorEncoders, SerialRate, SlaveBus};
use crate::{MasterConfig, MasterShared};

/// Stop the motors and build the controller in `shared`: what runs before the tasks. False
/// for a drive geometry it cannot run (a build-time mistake): then no task may run, and the
/// motors stay off for good.
pub fn start(motors: &mut impl MotorDrivers, shared: &MasterShared, config: &MasterConfig) -> bool {
    motors.stop();
    shared.start(config)
}

/// Reassemble host frames and hand each message to the controller.
///
/// `rx.read` must be cancel-safe (a read dropped before it finished loses no byte), as
/// embassy's DMA ring-buffered UART reader is: while play/record streams move, a read that
/// has waited [`STREAM_TX_PERIOD`] is dropped and asked again, so the bytes come in at least
/// that often. That reader itself finishes only when the line goes idle or half its buffer
/// fills, and a host streaming back to back may keep the line busy: half of 2 KiB is 89 ms
/// at 115 200 baud, far behind the acknowledgements the stream waits for.
pub async fn host_rx_task(mut rx: impl Read, shared: &MasterShared) -> ! {
    let mut decoder = FrameDecoder::new();
    let mut buf = [0u8; 64];
    loop {
        let streaming = shared.with(|c| c.streaming()).unwrap_or(false);
        let read = if streaming {
            match select(rx.read(&mut buf), Timer::after(STREAM_TX_PERIOD)).await {
                Either::First(read) => read,
                Either::Second(()) => continue,
            }
        } else {
            rx.read(&mut buf).await
        };
        let n = match read {
            Ok(0) => {
                // Nothing to read (a closed emulated link): don't spin.
                Timer::after_millis(1).await;
                continue;
            }
            Ok(n) => n,
            // Framing/noise/overrun errors lose bytes; the CRC catches the damaged frame.
            Err(_) => {
                shared.with(|c| c.on_host_frame_error());
                continue;
            }
        };
        for &byte in &buf[..n] {
            match decoder.push::<HostToMaster>(byte) {
                None => {}
                Some(Ok(msg)) => {
                    let reply = shared
                        .with(|c| c.on_host_message(Instant::now(), msg))
                        .flatten();
                    if let Some(reply) = reply {
                        // Replies are rare; if the queue is full the host is not reading and
                        // a dropped reply is the right outcome.
                        let _ = shared.replies.try_send(reply);
                    }
                }
                Some(Err(_)) => {
                    shared.with(|c| c.on_host_frame_error());
                }
            }
        }
        // A read returns at once while bytes wait: without a yield between chunks, a backlog
        // (a burst at 2 Mbaud) kept the other tasks waiting for milliseconds (the SPI poll
        // among them, which dated its exchange's end then, 2.4 ms after the slave re-armed: a
        // clock jump the controller took for a slave reset, until the bus dated it itself).
        embassy_futures::yield_now().await;
    }
}

/// How often the host side checks the play/record streams for a frame to send while they
/// move (`Controller::streaming`).
const STREAM_TX_PERIOD: Duration = Duration::from_micros(500);
/// And while they stand: a stream's first frame (the ack of the host's first events) then
/// waits at most this long, and the task wakes a tenth as often when nothing streams (a
/// thousand wake-ups a second were a third of an emulated master's polls, 2.8 % of an
/// emulation's instructions).
const STREAM_IDLE_PERIOD: Duration = Duration::from_millis(10);

/// Send replies as they come, stream frames (acks, reports) as they are due, and telemetry
/// at a fixed rate; switch the port's rate when a `BaudSet` answer is out, and back to the
/// power-on rate when the switch did not work.
pub async fn host_tx_task(
    mut tx: impl Write + SerialRate,
    shared: &MasterShared,
    config: &MasterConfig,
) -> ! {
    let mut ticker = Ticker::every(Duration::from_micros(config.telemetry_period_us as u64));
    let mut stream_period = STREAM_IDLE_PERIOD;
    let mut streams = Ticker::every(stream_period);
    let mut buf = [0u8; serial::MAX_FRAME];
    loop {
        let streaming = shared.with(|c| c.streaming()).unwrap_or(false);
        let period = if streaming {
            STREAM_TX_PERIOD
        } else {
            STREAM_IDLE_PERIOD
        };
        if period != stream_period {
            stream_period = period;
            streams = Ticker::every(period);
        }
        let msg = match select3(shared.replies.receive(), ticker.next(), streams.next()).await {
            Either3::First(reply) => reply,
            // While play/record streams move, they have the line: telemetry waits.
            Either3::Second(()) => {
                let fallback = shared
                    .with(|c| c.baud_fallback_due(Instant::now()))
                    .flatten();
                if let Some(baud) = fallback {
                    if tx.set_baud(baud) {
                        shared.with(|c| c.baud_switched(Instant::now(), baud));
                    }
                }
                match shared.with(|c| (!c.streaming()).then(|| c.telemetry(Instant::now()))) {
                    Some(Some(t)) => MasterToHost::Telemetry(t),
                    _ => continue,
                }
            }
            Either3::Third(()) => match shared.with(|c| c.poll_host_stream(Instant::now())) {
                Some(Some(m)) => m,
                _ => continue,
            },
        };
        if let Ok(frame) = serial::encode(&msg, &mut buf) {
            // A write error means the host side is gone; the host watchdog handles that.
            let _ = tx.write_all(frame).await;
        }
        if let MasterToHost::BaudSet { baud } = msg {
            // The answer must leave at the old rate, to its last stop bit.
            let _ = tx.flush().await;
            if tx.set_baud(baud) {
                shared.with(|c| c.baud_switched(Instant::now(), baud));
            }
        }
    }
}

/// Poll the slave at a fixed rate.
pub async fn slave_poll_task(
    mut bus: impl SlaveBus,
    shared: &MasterShared,
    config: &MasterConfig,
) -> ! {
    let normal = Duration::from_micros(config.poll_period_us as u64);
    let fast = Duration::from_micros(config.stream_poll_period_us as u64);
    let mut rx = [0u8; SPI_FRAME_LEN];
    let mut next = Instant::now();
    loop {
        // Faster while play/record streams move; the slave needs the gap to re-arm.
        let streaming = shared.with(|c| c.streaming()).unwrap_or(false);
        next += if streaming { fast } else { normal };
        let now = Instant::now();
        if next < now {
            next = now;
        }
        Timer::at(next).await;
        let Some(frame) = shared.with(|c| c.next_slave_frame()) else {
            continue;
        };
        let tx = spi::encode(&frame);
        let result = bus.exchange(&tx, &mut rx).await;
        shared.with(|c| match result {
            // Dated by the bus: when the last bit went, not when this task ran again.
            Ok(end) => c.on_slave_frame(end, spi::decode::<SlaveFrame>(&rx)),
            Err(_) => c.on_slave_bus_error(Instant::now()),
        });
    }
}

/// Fixed-rate control: read the motor encoders, decide, then drive the motors.
pub async fn control_task(
    mut motors: impl MotorDrivers,
    mut encoders: impl MotorEncoders,
    shared: &MasterShared,
    config: &MasterConfig,
) -> ! {
    let mut ticker = Ticker::every(Duration::from_micros(config.control_period_us as u64));
    loop {
        ticker.next().await;
        let counts = encoders.counts();
        let now = Instant::now();
        match shared.with(|c| {
            c.on_motor_counts(now, counts);
            c.control(now)
        }) {
            Some(Drive::Duty(d)) => motors.set_duty(d),
            _ => motors.stop(),
        }
    }
}
