//! A recording slave's report stream as `record` reads it: records COBS-framed, each ending in
//! 0x00 ([`protocol::spi::frame_report`]), so one that does not decode is passed over and the
//! next is read as if nothing had happened. (While playing the records are back to back:
//! `play` reads them with postcard directly.)

use protocol::spi::{unframe_report, Report, REPORT_FRAME_MAX};

/// What the next frame of the stream holds.
#[derive(Debug, PartialEq)]
pub enum Frame {
    Record(Report),
    /// A frame that is no record, starting at this byte of the stream (or, with no end within
    /// a record's longest, that many bytes dropped).
    Bad {
        at: u64,
    },
}

/// Bytes of the stream in, whole frames out; holds at most one frame's bytes.
#[derive(Default)]
pub struct ReportReader {
    buf: Vec<u8>,
    /// Stream offset of `buf[0]`.
    offset: u64,
}

impl ReportReader {
    pub fn push(&mut self, bytes: &[u8]) {
        self.buf.extend_from_slice(bytes);
    }

    /// The next whole frame, if its end has come.
    pub fn next_frame(&mut self) -> Option<Frame> {
        let at = self.offset;
        match self.buf.iter().position(|&b| b == 0) {
            Some(end) => {
                let mut frame: Vec<u8> = self.buf.drain(..=end).collect();
                frame.pop();
                self.offset += end as u64 + 1;
                Some(match unframe_report(&mut frame) {
                    Some(r) => Frame::Record(r),
                    None => Frame::Bad { at },
                })
            }
            // Longer than any record without an end: not one; what there is goes.
            None if self.buf.len() > REPORT_FRAME_MAX => {
                self.offset += self.buf.len() as u64;
                self.buf.clear();
                Some(Frame::Bad { at })
            }
            None => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use protocol::spi::frame_report;

    fn framed(r: &Report) -> Vec<u8> {
        let mut out = [0u8; REPORT_FRAME_MAX];
        let n = frame_report(r, &mut out).unwrap();
        out[..n].to_vec()
    }

    #[test]
    fn records_cut_anywhere_come_out_whole_and_a_bad_one_is_passed_over() {
        let a = Report::Lost {
            events: 3,
            updates: 0,
        };
        // Its postcard bytes hold zeros: the framing takes them out.
        let b = Report::BadEvents { offset: 0 };
        let mut stream = framed(&a);
        let bad_at = stream.len() as u64;
        stream.extend_from_slice(&[0xFF, 0xFF, 0xFF, 0]); // a frame that is no record
        stream.extend(framed(&b));
        stream.extend(framed(&a));
        let mut reader = ReportReader::default();
        let mut got = Vec::new();
        for piece in stream.chunks(3) {
            reader.push(piece);
            while let Some(f) = reader.next_frame() {
                got.push(f);
            }
        }
        assert_eq!(
            got,
            vec![
                Frame::Record(a),
                Frame::Bad { at: bad_at },
                Frame::Record(b),
                Frame::Record(a)
            ]
        );
    }

    #[test]
    fn bytes_without_an_end_are_dropped_not_kept() {
        let mut reader = ReportReader::default();
        reader.push(&[7; 4 * REPORT_FRAME_MAX]);
        assert_eq!(reader.next_frame(), Some(Frame::Bad { at: 0 }));
        assert_eq!(reader.next_frame(), None);
        reader.push(&framed(&Report::BadEvents { offset: 9 }));
        assert_eq!(
            reader.next_frame(),
            Some(Frame::Record(Report::BadEvents { offset: 9 }))
        );
    }
}
