//! Where each event of a stream was in its file, so that a check made after reading (an
//! encoder the robot does not have) can name the line as the reader's own errors do.

/// The header's line, and for each comment or blank line after it, how many events came
/// before it. Events are not stored with their line (8 bytes a row); the lines in between are
/// at most [`super::MAX_OTHER_LINES`], 4 MB of these at worst.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Lines {
    pub(super) header: u64,
    pub(super) gaps: Vec<u32>,
}

impl Lines {
    /// The 1-based line of the file on which event `index` (into `TickStream::events`) is.
    pub fn of(&self, index: usize) -> u64 {
        let skipped = self.gaps.partition_point(|&g| g as usize <= index);
        self.header + 1 + index as u64 + skipped as u64
    }
}

#[cfg(test)]
mod tests {
    use super::super::read_from;
    use std::path::Path;

    #[test]
    fn each_event_is_found_on_its_line_past_comments_and_blank_lines() {
        let text = "# omnibench tick stream v1\n# a\n\nt_ns,kind,id,value,x_m,y_m,theta_rad\n\
                    0,truth,,,0,0,0\n# b\n,,,\n\"\",\"\"\n1,tick,0,1,,,\n2,tick,1,1,,,\n\n\
                    3,truth,,,0,0,0\n";
        let (stream, lines) =
            super::super::read::parse_with_lines(text.as_bytes(), Path::new("t.csv"), &mut |_| {
                Ok(())
            })
            .unwrap();
        assert_eq!(
            stream,
            read_from(text.as_bytes(), Path::new("t.csv")).unwrap()
        );
        let found: Vec<u64> = (0..stream.events.len()).map(|i| lines.of(i)).collect();
        assert_eq!(found, [5, 9, 10, 12]);
    }
}
