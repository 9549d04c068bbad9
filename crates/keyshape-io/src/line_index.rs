//! Where a table's lines are, for the rows' true line numbers, and each line's length
//! bounded as it is read.

/// A reader that notes where the lines of what passes through it have content, so a
/// record's position gives its true line. The csv crate positions a record where parsing
/// resumed after the previous one — before any blank lines it skips, and on the `\n` of a
/// CRLF — so its own line count is off after a blank line and with CRLF line ends. Only
/// the lines read ahead of the last record asked about are kept: memory does not grow with
/// the file.
pub(crate) struct LineIndex<R> {
    inner: R,
    /// Bytes read so far.
    pos: u64,
    /// Lines read but not yet passed: (offset of their `\n`, offset of their first byte
    /// that is not `\r` or `\n`, if any).
    lines: std::collections::VecDeque<(u64, Option<u64>)>,
    /// The first content byte of the line being read.
    open: Option<u64>,
    /// Lines already passed.
    passed: u64,
    /// Bytes read since the last `\n`: a line longer than [`crate::MAX_LINE_BYTES`] is an
    /// error here, before the csv reader has stored it (a 300 MB line cost 1 GB).
    pub(crate) run: usize,
}

impl<R> LineIndex<R> {
    pub(crate) fn new(inner: R) -> Self {
        LineIndex {
            inner,
            pos: 0,
            lines: Default::default(),
            open: None,
            passed: 0,
            run: 0,
        }
    }

    /// The line (from 1) of the first content at or after byte `at`; calls must not go
    /// backwards.
    pub(crate) fn line_at(&mut self, at: u64) -> u64 {
        while self.lines.front().is_some_and(|&(nl, _)| nl < at) {
            self.lines.pop_front();
            self.passed += 1;
        }
        let mut line = self.passed + 1;
        for &(_, first) in &self.lines {
            if first.is_some_and(|c| c >= at) {
                return line;
            }
            line += 1;
        }
        line
    }
}

impl<R: std::io::Read> std::io::Read for LineIndex<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        for (i, b) in buf[..n].iter().enumerate() {
            let at = self.pos + i as u64;
            self.run += 1;
            match b {
                b'\n' => {
                    self.lines.push_back((at, self.open.take()));
                    self.run = 0;
                }
                b'\r' => {}
                _ => {
                    self.open.get_or_insert(at);
                }
            }
            if self.run > crate::MAX_LINE_BYTES {
                let line = self.passed + self.lines.len() as u64 + 1;
                return Err(std::io::Error::new(
                    std::io::ErrorKind::InvalidData,
                    format!(
                        "line {line} is longer than {} bytes: not a text table",
                        crate::MAX_LINE_BYTES
                    ),
                ));
            }
        }
        self.pos += n as u64;
        Ok(n)
    }
}
