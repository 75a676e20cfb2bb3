//! [`ReadAhead`]: a [`RowReader`] on its own thread, one batch of rows ahead of the caller.

use std::path::PathBuf;

use std::io::BufRead;

use super::{CsvError, RowReader};

/// Rows per batch of [`ReadAhead`]: large enough that the channel costs nothing per row, small enough that
/// the batches in flight (at most four) stay under a megabyte.
pub const READ_AHEAD_ROWS: usize = 8192;

/// One batch of rows from [`ReadAhead`]: the required columns of each row, row after row.
#[derive(Debug, Default)]
pub struct Batch {
    /// `width` values per row, in the order asked for.
    pub values: Vec<f64>,
    /// Bytes of the file consumed up to the end of this batch (for progress reports).
    pub bytes_read: u64,
}

enum Msg {
    Rows(Batch),
    Done { rows: u64 },
    Failed(CsvError),
}

/// A [`RowReader`] running on its own thread, one batch ahead: the file is read, checked and parsed on one
/// core while the caller computes on another. Same rows, same checks and the same first error as the
/// reader alone, in memory bounded by four batches whatever the file's length (batches are recycled).
pub struct ReadAhead {
    file: PathBuf,
    width: usize,
    rx: Option<std::sync::mpsc::Receiver<Msg>>,
    recycle: std::sync::mpsc::Sender<Batch>,
    thread: Option<std::thread::JoinHandle<()>>,
    rows: Option<u64>,
}

impl ReadAhead {
    /// Start reading `reader`'s rows on a new thread.
    pub fn spawn<R: BufRead + Send + 'static>(mut reader: RowReader<R>) -> ReadAhead {
        let width = reader.row.len();
        let file = reader.checker.file.clone();
        let (tx, rx) = std::sync::mpsc::sync_channel::<Msg>(2);
        let (recycle, spare) = std::sync::mpsc::channel::<Batch>();
        let thread = std::thread::spawn(move || {
            loop {
                let mut batch = spare.try_recv().unwrap_or_else(|_| Batch {
                    values: Vec::with_capacity(READ_AHEAD_ROWS * width),
                    bytes_read: 0,
                });
                batch.values.clear();
                let mut end = false;
                while batch.values.len() < READ_AHEAD_ROWS * width {
                    match reader.next_row() {
                        Ok(Some(row)) => batch.values.extend_from_slice(row),
                        Ok(None) => {
                            end = true;
                            break;
                        }
                        Err(e) => {
                            // The rows before the error first, as the reader alone would give them.
                            if !batch.values.is_empty() {
                                batch.bytes_read = reader.bytes_read();
                                if tx.send(Msg::Rows(batch)).is_err() {
                                    return;
                                }
                            }
                            let _ = tx.send(Msg::Failed(e));
                            return;
                        }
                    }
                }
                batch.bytes_read = reader.bytes_read();
                if !batch.values.is_empty() && tx.send(Msg::Rows(batch)).is_err() {
                    // The consumer has gone (it stopped on an error of its own).
                    return;
                }
                if end {
                    let _ = tx.send(Msg::Done {
                        rows: reader.rows(),
                    });
                    return;
                }
            }
        });
        ReadAhead {
            file,
            width,
            rx: Some(rx),
            recycle,
            thread: Some(thread),
            rows: None,
        }
    }

    /// Values per row.
    pub fn width(&self) -> usize {
        self.width
    }

    /// The next batch, `None` after the last one; the reader's error where it met one.
    pub fn next_batch(&mut self) -> Result<Option<Batch>, CsvError> {
        let Some(rx) = &self.rx else {
            return Ok(None);
        };
        match rx.recv() {
            Ok(Msg::Rows(b)) => Ok(Some(b)),
            Ok(Msg::Done { rows }) => {
                self.rows = Some(rows);
                self.rx = None;
                Ok(None)
            }
            Ok(Msg::Failed(e)) => {
                self.rx = None;
                Err(e)
            }
            Err(_) => {
                self.rx = None;
                Err(CsvError::Io {
                    file: self.file.clone(),
                    source: std::io::Error::other("the reading thread stopped without a result"),
                })
            }
        }
    }

    /// Give a batch back for reuse (optional: without it the reader allocates a new one).
    pub fn recycle(&self, batch: Batch) {
        let _ = self.recycle.send(batch);
    }

    /// Data rows read, once [`ReadAhead::next_batch`] has returned `None`.
    pub fn rows(&self) -> Option<u64> {
        self.rows
    }
}

impl Drop for ReadAhead {
    fn drop(&mut self) {
        // Closing the channel ends the thread at its next send; then wait for it.
        self.rx = None;
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}
