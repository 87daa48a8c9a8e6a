//! The flight recorder: a node's journal ([`ayllu_core::journal`]) written to an MCAP file
//! that Foxglove opens as it is and `ayllu replay` plays back (spec/flight-recorder.md).
//!
//! A [`Recorder`] turns the core's journal on and, each time it is drained (every
//! [`crate::Node::step`]), hands what was journaled to a writer thread; the thread encodes
//! each entry as one CDR message ([`crate::recording_cdr`]) in a reused buffer and writes MCAP
//! segments.
//!
//! What it promises:
//! * The node never waits on the disk: batches go to the writer through a queue bounded in
//!   entries ([`RecordOptions::queue`]); while it is full, entries wait in the recorder up to
//!   the journal's capacity, and past that they are dropped and counted, and the recording
//!   says so with a `gap` entry (a replay stops there). Memory is bounded by the journal's
//!   capacity (twice: in the core and waiting here), the queue and one MCAP chunk.
//! * Files are bounded: a segment is closed before it would pass
//!   [`RecordOptions::segment_bytes`], and the next one opened (`run.mcap`, `run.1.mcap`,
//!   `run.2.mcap`, ...) while the segments together stay under [`RecordOptions::max_bytes`];
//!   then recording stops (the beginning is kept: a replay needs it) and what could not be
//!   written is counted.
//! * Recording changes nothing the node does: the journal only reads what the core does.
//! * Each segment is a complete MCAP file once closed (on [`Recorder::finish`] or drop), and
//!   a chunk is flushed at least every [`FLUSH_INTERVAL`], so a node killed outright loses
//!   at most that much.
//! * A rolling recorder ([`RecordOptions::keep_last`]) keeps the end instead of the
//!   beginning: every [`checkpoint_interval`] of node time it takes a checkpoint of the core
//!   ([`NodeCore::snapshot`], a copy of its state made on the node's thread, encoded by the
//!   writer's) and starts a new segment with it; whole runs of segments (a checkpoint and
//!   what follows it) are deleted once the next run alone reaches back `keep_last`, or to
//!   stay under [`RecordOptions::max_bytes`]. The files kept then cover at least the last
//!   `keep_last` (when the byte cap allows) and at most that plus one interval, and a replay
//!   starts from the checkpoint of the oldest run kept.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, SyncSender, TryRecvError, TrySendError};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration as StdDuration, Instant as StdInstant, SystemTime, UNIX_EPOCH};

use std::collections::VecDeque;
use std::sync::atomic::AtomicBool;

use ayllu_core::{Entry, Event, Instant, JournalBatch, JournalItem, NodeCore, Snapshot};

use crate::error::Error;
use crate::recording_cdr::{encode_checkpoint_into, encode_item, SCHEMA, SCHEMA_NAME};
use crate::recording_format::{Topic, METADATA, PROFILE, VERSION};

/// A chunk is closed and written at least this often, so a crash loses little.
pub const FLUSH_INTERVAL: StdDuration = StdDuration::from_millis(500);

/// How long the writer sleeps between looks at its queue while there is work.
const WRITER_NAP_MIN: StdDuration = StdDuration::from_millis(1);

/// How long the writer sleeps between looks at its queue at most, once idle (doubling from
/// [`WRITER_NAP_MIN`]): at 1.5 M entries a second a burst after an idle spell queues some
/// 24 000 entries before the writer looks, a tenth of the queue's default bound.
const WRITER_NAP_MAX: StdDuration = StdDuration::from_millis(16);

/// The smallest segment accepted (a segment holds its header, schemas and summary).
pub const MIN_SEGMENT_BYTES: u64 = 64 * 1024;

/// How a node records.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RecordOptions {
    /// All segments together stay under this many bytes; recording stops there (default 1 GiB).
    pub max_bytes: u64,
    /// One segment stays under this many bytes (default 64 MiB, at least
    /// [`MIN_SEGMENT_BYTES`]); then the next is opened.
    pub segment_bytes: u64,
    /// Journal entries the core holds between two drains, at most (default 65 536).
    pub journal_capacity: usize,
    /// Entries waiting for the writer thread, at most (default 262 144: a value or a write is
    /// a 24-byte record, other entries 72 bytes, plus what text, bytes and vectors hold).
    pub queue: usize,
    /// Keep only about the last this long (node time), deleting older segments: a rolling
    /// recording (see the module docs). `None` (the default): keep the beginning, stop at the
    /// cap.
    pub keep_last: Option<StdDuration>,
}

impl Default for RecordOptions {
    fn default() -> Self {
        RecordOptions {
            max_bytes: 1 << 30,
            segment_bytes: 64 << 20,
            journal_capacity: 65_536,
            queue: 262_144,
            keep_last: None,
        }
    }
}

impl RecordOptions {
    /// Cap the whole recording at `max_bytes`; segments are at most as large.
    pub fn max_bytes(mut self, max_bytes: u64) -> Self {
        self.max_bytes = max_bytes;
        self.segment_bytes = self.segment_bytes.min(max_bytes);
        self
    }

    /// Keep only about the last `window` of the node's life (a rolling recording: see the
    /// module docs).
    pub fn keep_last(mut self, window: StdDuration) -> Self {
        self.keep_last = Some(window);
        self
    }
}

/// How often a rolling recorder keeping the last `window` takes a checkpoint: a quarter of the
/// window (so the files hold at most a quarter more than asked), and not more often than every
/// second (a checkpoint copies the node's whole state).
pub fn checkpoint_interval(window: StdDuration) -> StdDuration {
    (window / 4).max(StdDuration::from_secs(1))
}

/// What the recorder hands its writer thread: journal entries, then, in a rolling recording,
/// maybe a checkpoint taken after them.
struct Batch {
    entries: JournalBatch,
    checkpoint: Option<Box<Snapshot>>,
}

/// What a recorder has done so far.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct RecordStats {
    /// Journal entries written.
    pub written: u64,
    /// Entries dropped because the writer's queue was full (the disk was slow).
    pub dropped_queue: u64,
    /// Entries dropped by the core's journal (more in one loop turn than its capacity).
    pub dropped_journal: u64,
    /// Entries not written because [`RecordOptions::max_bytes`] was reached.
    pub dropped_cap: u64,
    /// Bytes written, all segments together.
    pub bytes: u64,
    /// Segments written (files).
    pub segments: u64,
    /// Segments a rolling recorder deleted (see [`RecordOptions::keep_last`]).
    pub deleted: u64,
    /// Entries journaled and not written yet (waiting for the writer thread): a recorder that
    /// keeps up brings it back to 0 between bursts. A rolling recorder checkpoints only when
    /// nothing waits, so a writer that stays behind also delays checkpoints.
    pub waiting: u64,
    /// The first write error, if any (recording stopped there).
    pub error: Option<String>,
}

#[derive(Default)]
struct Shared {
    written: AtomicU64,
    dropped_queue: AtomicU64,
    /// Entries handed to the writer and not written yet.
    queued: AtomicU64,
    dropped_cap: AtomicU64,
    bytes: AtomicU64,
    segments: AtomicU64,
    /// Segments a rolling recorder deleted.
    deleted: AtomicU64,
    /// The writer asks for a checkpoint early (a rolling segment filled before its time).
    want_checkpoint: AtomicBool,
    error: Mutex<Option<String>>,
}

/// Records one node's core. See the module docs.
pub struct Recorder {
    path: PathBuf,
    queue: Option<SyncSender<Batch>>,
    /// Emptied batches the writer hands back, so the journal's buffer is swapped, not copied.
    recycled: Receiver<JournalBatch>,
    thread: Option<JoinHandle<()>>,
    shared: Arc<Shared>,
    batch: JournalBatch,
    /// The writer refused the batch held here: entries the journal loses meanwhile are the
    /// writer's loss.
    behind: bool,
    dropped_journal: u64,
    /// Entries that may wait in the writer's queue, at most ([`RecordOptions::queue`]).
    queue_limit: u64,
    /// A rolling recorder's checkpoint interval, and when the next checkpoint is due.
    rolling: Option<(ayllu_core::Duration, Instant)>,
}

/// The file of segment `n`: `run.mcap`, then `run.1.mcap`, `run.2.mcap`, ...
pub fn segment_path(first: &Path, n: u64) -> PathBuf {
    if n == 0 {
        return first.to_path_buf();
    }
    let stem = first.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let name = match first.extension() {
        Some(ext) => format!("{stem}.{n}.{}", ext.to_string_lossy()),
        None => format!("{stem}.{n}"),
    };
    first.with_file_name(name)
}

/// The numbers of the segments of recording `first` that exist, ascending: `run.mcap` is 0,
/// `run.N.mcap` is N. A rolling recording deletes its oldest, so the first may not be 0.
pub fn segment_numbers(first: &Path) -> Vec<u64> {
    let mut found: Vec<u64> = Vec::new();
    if first.is_file() {
        found.push(0);
    }
    let dir = match first.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let Ok(entries) = std::fs::read_dir(&dir) else { return found };
    let stem = first.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let ext = first.extension().map(|e| format!(".{}", e.to_string_lossy())).unwrap_or_default();
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        let n = name
            .strip_prefix(&stem)
            .and_then(|r| r.strip_prefix('.'))
            .and_then(|r| r.strip_suffix(ext.as_str()))
            .and_then(|n| n.parse::<u64>().ok())
            .filter(|&n| n > 0 && segment_path(first, n).file_name() == Some(entry.file_name().as_os_str()));
        found.extend(n);
    }
    found.sort_unstable();
    found
}

impl Recorder {
    /// Start recording `core` into `path` (and its following segments). The core must be new
    /// (no class defined, nothing created or joined): a replay rebuilds the node from its
    /// first definition. Segment files left by an earlier recording of the same name are
    /// removed, so they cannot be mistaken for this one's.
    pub fn start(core: &mut NodeCore, path: &Path, options: RecordOptions) -> Result<Recorder, Error> {
        if !core.is_pristine() {
            return Err(Error::Recording {
                what: "start recording before defining classes or creating behaviors: a replay rebuilds the node from \
                 its first definition"
                    .into(),
            });
        }
        if options.segment_bytes < MIN_SEGMENT_BYTES || options.max_bytes < MIN_SEGMENT_BYTES {
            return Err(Error::Recording {
                what: format!("a recording needs at least {MIN_SEGMENT_BYTES} bytes per segment"),
            });
        }
        let rolling = options.keep_last.map(|w| {
            ayllu_core::Duration::from_nanos(u64::try_from(checkpoint_interval(w).as_nanos()).unwrap_or(u64::MAX))
        });
        let shared = Arc::new(Shared::default());
        for n in segment_numbers(path).into_iter().filter(|&n| n > 0) {
            let _ = std::fs::remove_file(segment_path(path, n));
        }
        let mut writer = SegmentWriter {
            first: path.to_path_buf(),
            node: core.id().0,
            epoch_ns: epoch_ns(core),
            options: options.clone(),
            current: None,
            index: 0,
            closed_bytes: 0,
            seq: 0,
            capped: false,
            shared: shared.clone(),
            runs: VecDeque::from([Run { first: 0, start: core.now() }]),
            sizes: BTreeMap::new(),
            buf: Vec::with_capacity(1024),
            unreported: 0,
        };
        writer.current = Some(writer.open(0, writer.segment_budget(options.max_bytes))?);
        shared.segments.store(1, Ordering::Relaxed);
        // The channel's own bound only backs up `Shared::queued`, which is the real one.
        let (tx, rx) = sync_channel(1024);
        let (recycle, recycled) = sync_channel(16);
        let base = core.sequence_base();
        let thread = std::thread::Builder::new()
            .name("ayllu-recorder".into())
            .spawn(move || writer.run(rx, recycle))
            .map_err(|e| Error::Recording { what: format!("recorder thread: {e}") })?;
        core.start_journal(options.journal_capacity);
        // The sequence base was set before the journal ran (the runtime sets it at birth).
        if base > 0 {
            core.set_sequence_base(base);
        }
        Ok(Recorder {
            path: path.to_path_buf(),
            queue: Some(tx),
            recycled,
            thread: Some(thread),
            shared,
            batch: JournalBatch::default(),
            behind: false,
            dropped_journal: 0,
            queue_limit: options.queue.max(1) as u64,
            rolling: rolling.map(|every| (every, core.now() + every)),
        })
    }

    /// The first segment's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Hand what the core journaled since the last drain to the writer; never waits. While the
    /// writer's queue is full the batch it refused waits here and is offered again at the next
    /// drain before anything more is taken, so what the node journals meanwhile waits in the
    /// journal, up to its capacity; past it the journal loses entries, counts them (as the
    /// writer's: `dropped_queue`) and marks the hole in the recording with a gap. Nothing is
    /// copied while the writer is behind.
    pub fn drain(&mut self, core: &mut NodeCore) {
        if !self.batch.is_empty() && !self.send() {
            return;
        }
        if self.batch.capacity() == 0 {
            if let Ok(empty) = self.recycled.try_recv() {
                self.batch = empty;
            }
        }
        core.take_journal_batch(&mut self.batch);
        self.count_lost(0);
        if self.batch.is_empty() || self.send() {
            self.checkpoint(core);
        }
    }

    /// Count what the journal lost before or among the entries just taken (the batch's losses
    /// beyond `before`, those of entries it held already): the writer's loss if it was behind
    /// (the recorder was not taking), else the journal's.
    fn count_lost(&mut self, before: u64) {
        let lost = self.batch.journal_lost() - before;
        if self.behind {
            self.shared.dropped_queue.fetch_add(lost, Ordering::Relaxed);
        } else {
            self.dropped_journal += lost;
        }
    }

    /// Offer the batch to the writer: `false` if its queue is full (the batch stays here).
    fn send(&mut self) -> bool {
        let Some(queue) = &self.queue else {
            self.batch.clear();
            return true;
        };
        let batch = Batch { entries: std::mem::take(&mut self.batch), checkpoint: None };
        let n = batch.entries.len() as u64;
        // Counted before it is sent: the writer subtracts it once written, maybe at once.
        let queued = self.shared.queued.fetch_add(n, Ordering::AcqRel);
        let sent = if queued + n > self.queue_limit { Err(TrySendError::Full(batch)) } else { queue.try_send(batch) };
        if sent.is_err() {
            self.shared.queued.fetch_sub(n, Ordering::AcqRel);
        }
        match sent {
            Ok(()) => {
                self.behind = false;
                true
            }
            Err(TrySendError::Full(batch)) => {
                self.batch = batch.entries;
                self.behind = true;
                false
            }
            Err(TrySendError::Disconnected(_)) => {
                self.queue = None;
                true
            }
        }
    }

    /// A rolling recorder's checkpoint, when one is due (or the writer asked for one early):
    /// taken only when every entry journaled so far has gone to the writer, so that it stands
    /// exactly between two journal positions. If the queue is full it is tried again at the
    /// next drain, at a later position.
    fn checkpoint(&mut self, core: &NodeCore) {
        let Some((every, due)) = self.rolling else { return };
        let asked = self.shared.want_checkpoint.load(Ordering::Relaxed);
        if (core.now() < due && !asked) || !self.batch.is_empty() {
            return;
        }
        let Some(queue) = &self.queue else { return };
        let batch = Batch { entries: JournalBatch::default(), checkpoint: Some(Box::new(core.snapshot())) };
        if queue.try_send(batch).is_ok() {
            self.shared.want_checkpoint.store(false, Ordering::Relaxed);
            self.rolling = Some((every, core.now() + every));
        }
    }

    /// What was recorded so far.
    pub fn stats(&self) -> RecordStats {
        let s = &self.shared;
        RecordStats {
            written: s.written.load(Ordering::Relaxed),
            dropped_queue: s.dropped_queue.load(Ordering::Relaxed),
            dropped_journal: self.dropped_journal,
            dropped_cap: s.dropped_cap.load(Ordering::Relaxed),
            bytes: s.bytes.load(Ordering::Relaxed),
            segments: s.segments.load(Ordering::Relaxed),
            deleted: s.deleted.load(Ordering::Relaxed),
            waiting: s.queued.load(Ordering::Relaxed) + self.batch.len() as u64,
            error: s.error.lock().map(|e| e.clone()).unwrap_or(None),
        }
    }

    /// Drain `core` a last time, stop its journal, close the files and say what was recorded.
    /// This waits for the writer to write what is queued.
    pub fn finish(mut self, core: &mut NodeCore) -> RecordStats {
        let before = self.batch.journal_lost();
        core.take_journal_batch(&mut self.batch);
        self.count_lost(before);
        core.stop_journal();
        if let Some(queue) = &self.queue {
            let batch = std::mem::take(&mut self.batch);
            if !batch.is_empty() {
                self.shared.queued.fetch_add(batch.len() as u64, Ordering::AcqRel);
                let _ = queue.send(Batch { entries: batch, checkpoint: None });
            }
        }
        self.close();
        self.stats()
    }

    fn close(&mut self) {
        self.queue = None;
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for Recorder {
    fn drop(&mut self) {
        self.close();
    }
}

/// A file that counts what reaches it (the segment's size, without asking the OS).
struct Counted {
    file: BufWriter<File>,
    pos: u64,
    end: Arc<AtomicU64>,
}

impl Write for Counted {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let n = self.file.write(buf)?;
        self.pos += n as u64;
        self.end.fetch_max(self.pos, Ordering::Relaxed);
        Ok(n)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.file.flush()
    }
}

impl Seek for Counted {
    fn seek(&mut self, to: SeekFrom) -> std::io::Result<u64> {
        self.pos = self.file.seek(to)?;
        Ok(self.pos)
    }
}

/// One open segment file.
struct Segment {
    mcap: mcap::Writer<Counted>,
    channels: [u16; Topic::ALL.len()],
    /// Bytes that reached the file.
    size: Arc<AtomicU64>,
    /// This segment's share of the byte budget.
    budget: u64,
    last_flush: StdInstant,
}

/// The writer thread's state.
struct SegmentWriter {
    first: PathBuf,
    node: u32,
    /// The node's clock zero as Unix time (ns), for the messages' log times.
    epoch_ns: u64,
    options: RecordOptions,
    current: Option<Segment>,
    index: u64,
    /// Bytes of the segments already closed.
    closed_bytes: u64,
    seq: u64,
    capped: bool,
    shared: Arc<Shared>,
    /// A rolling recording's runs kept, oldest first: each a checkpoint (or the beginning) and
    /// the segments after it up to the next run's first.
    runs: VecDeque<Run>,
    /// The size of each closed segment kept, by number.
    sizes: BTreeMap<u64, u64>,
    /// The message being encoded: reused, so that an entry costs no allocation.
    buf: Vec<u8>,
    /// Entries written and not yet added to `Shared::written`: added once a batch, not once an
    /// entry (an atomic operation per entry on a line the node's thread also touches).
    unreported: u64,
}

/// A run of segments: the first one's number and the node time it starts at.
#[derive(Clone, Copy, Debug)]
struct Run {
    first: u64,
    start: Instant,
}

/// The size of an MCAP chunk: small enough that a segment holds several and a crash loses
/// little, large enough that chunk overhead stays a few percent.
fn chunk_bytes(options: &RecordOptions) -> u64 {
    (options.segment_bytes / 8).clamp(4096, 256 * 1024)
}

impl SegmentWriter {
    fn open(&self, index: u64, budget: u64) -> Result<Segment, Error> {
        let path = segment_path(&self.first, index);
        let io = |e: &dyn std::fmt::Display| Error::Recording { what: format!("recording {}: {e}", path.display()) };
        let file = File::create(&path).map_err(|e| io(&e))?;
        let size = Arc::new(AtomicU64::new(0));
        let counted = Counted { file: BufWriter::new(file), pos: 0, end: size.clone() };
        let mut mcap = mcap::WriteOptions::new()
            .profile(PROFILE)
            .library(concat!("ayllu ", env!("CARGO_PKG_VERSION")))
            .compression(None)
            .chunk_size(Some(chunk_bytes(&self.options)))
            .create(counted)
            .map_err(|e| io(&e))?;
        let rolling = self.options.keep_last.is_some();
        let mut channels = [0u16; Topic::ALL.len()];
        let schema = mcap.add_schema(SCHEMA_NAME, "ros2msg", SCHEMA.as_bytes()).map_err(|e| io(&e))?;
        for (i, topic) in Topic::ALL.into_iter().enumerate() {
            // Only a rolling recording has checkpoints.
            if topic == Topic::Checkpoint && !rolling {
                continue;
            }
            channels[i] = mcap.add_channel(schema, topic.name(), "cdr", &BTreeMap::new()).map_err(|e| io(&e))?;
        }
        let mut metadata = BTreeMap::from([
            ("version".to_owned(), VERSION.to_owned()),
            ("node".to_owned(), self.node.to_string()),
            ("segment".to_owned(), index.to_string()),
            ("epoch_unix_ns".to_owned(), self.epoch_ns.to_string()),
        ]);
        if let Some(window) = self.options.keep_last {
            metadata.insert("keep_last_s".to_owned(), window.as_secs_f64().to_string());
        }
        mcap.write_metadata(&mcap::records::Metadata { name: METADATA.into(), metadata }).map_err(|e| io(&e))?;
        Ok(Segment { mcap, channels, size, budget, last_flush: StdInstant::now() })
    }

    fn fail(&mut self, e: impl std::fmt::Display) {
        if let Ok(mut slot) = self.shared.error.lock() {
            slot.get_or_insert_with(|| e.to_string());
        }
        self.capped = true;
        self.current = None;
    }

    /// Add the entries written since the last report to the shared count.
    fn report_written(&mut self) {
        if self.unreported > 0 {
            self.shared.written.fetch_add(std::mem::take(&mut self.unreported), Ordering::Relaxed);
        }
    }

    /// The writer's loop. It is never woken by the node: it sleeps, then takes every batch
    /// queued meanwhile, and sleeps again (a millisecond while there is work, up to
    /// [`WRITER_NAP_MAX`] while idle). Woken at every batch, it was placed by the scheduler on the
    /// node's own core whenever the other was busy (a waker's core is preferred), and its
    /// encoding was then counted in the node's loop: on a loaded 2-core host the recorded hop
    /// cost 10-40x the plain one where it costs 2-3x with the writer beside it
    /// (docs/performance.md).
    fn run(mut self, rx: Receiver<Batch>, recycle: SyncSender<JournalBatch>) {
        let mut nap = WRITER_NAP_MIN;
        loop {
            let mut worked = false;
            loop {
                match rx.try_recv() {
                    Ok(batch) => {
                        worked = true;
                        self.write_batch(batch, &recycle);
                    }
                    Err(TryRecvError::Empty) => break,
                    Err(TryRecvError::Disconnected) => {
                        self.report_written();
                        self.close_segment();
                        return;
                    }
                }
            }
            self.report_written();
            if let Some(seg) = self.current.as_mut() {
                if seg.last_flush.elapsed() >= FLUSH_INTERVAL {
                    seg.last_flush = StdInstant::now();
                    if let Err(e) = seg.mcap.flush() {
                        self.fail(e);
                    }
                }
            }
            nap = if worked { WRITER_NAP_MIN } else { (nap * 2).min(WRITER_NAP_MAX) };
            std::thread::sleep(nap);
        }
    }

    /// Write one batch's entries, hand the emptied batch back, and start a run at its
    /// checkpoint if it carries one.
    fn write_batch(&mut self, batch: Batch, recycle: &SyncSender<JournalBatch>) {
        let Batch { entries: mut batch, checkpoint } = batch;
        let n = batch.len() as u64;
        for item in batch.items() {
            self.write(item);
        }
        self.report_written();
        self.shared.queued.fetch_sub(n, Ordering::AcqRel);
        batch.clear();
        // Back to the recorder for the journal to fill again (dropped if it has enough).
        if batch.capacity() > 0 {
            let _ = recycle.try_send(batch);
        }
        if let Some(snapshot) = checkpoint {
            self.start_run(&snapshot);
        }
    }

    /// Room kept free in a segment for what closing it writes: the chunk being built and
    /// its message index, the summary (schemas, channels, statistics, an index entry per
    /// chunk), the end metadata and the footer.
    fn reserve(&self, seg: &Segment) -> u64 {
        let chunk = chunk_bytes(&self.options);
        let chunks = seg.size.load(Ordering::Relaxed) / chunk + 1;
        chunk + chunk / 2 + 8 * 1024 + 256 * chunks
    }

    fn fits(&self, seg: &Segment, len: u64) -> bool {
        seg.size.load(Ordering::Relaxed) + len + 64 + self.reserve(seg) <= seg.budget
    }

    /// Encode and write one entry, in the writer's reused buffer.
    fn write(&mut self, entry: JournalItem<'_>) {
        let mut data = std::mem::take(&mut self.buf);
        self.write_with(entry, &mut data);
        self.buf = data;
    }

    fn write_with(&mut self, entry: JournalItem<'_>, data: &mut Vec<u8>) {
        let at = entry.at();
        let seq = self.seq;
        self.seq += 1;
        if self.capped {
            self.shared.dropped_cap.fetch_add(1, Ordering::Relaxed);
            return;
        }
        data.clear();
        let topic = encode_item(seq, entry, data);
        let len = data.len() as u64;
        if !self.current.as_ref().is_some_and(|seg| self.fits(seg, len)) {
            // A rolling segment that fills before its checkpoint is due is followed by a
            // continuation segment, and the node is asked for a checkpoint at once.
            self.shared.want_checkpoint.store(true, Ordering::Relaxed);
            let open = self.current.as_ref().map_or(0, |seg| seg.size.load(Ordering::Relaxed));
            self.prune_for(open + self.segment_budget(self.options.max_bytes));
            let left = self.options.max_bytes.saturating_sub(self.closed_bytes + open);
            let budget = left.min(self.segment_budget(self.options.max_bytes));
            if budget < MIN_SEGMENT_BYTES {
                // Decided before closing, so that the last segment says the cap ended it.
                self.capped = true;
                self.shared.dropped_cap.fetch_add(1, Ordering::Relaxed);
                self.close_segment();
                return;
            }
            self.close_segment();
            self.index += 1;
            match self.open(self.index, budget) {
                Ok(seg) => {
                    self.current = Some(seg);
                    self.shared.segments.fetch_add(1, Ordering::Relaxed);
                }
                Err(e) => return self.fail(e),
            }
        }
        let Some(seg) = self.current.as_ref() else { return };
        if !self.fits(seg, len) {
            // One entry larger than a whole segment (a huge value): it is left out, and the
            // recording says so where it was.
            self.shared.dropped_cap.fetch_add(1, Ordering::Relaxed);
            let gap = Entry { at, event: Event::Gap { lost: 1 } };
            self.seq -= 1;
            return self.write(JournalItem::Entry(&gap));
        }
        let topic_ix = Topic::ALL.iter().position(|t| *t == topic).unwrap_or(0);
        let Some(seg) = self.current.as_mut() else { return };
        let time = self.epoch_ns.saturating_add(at.as_nanos());
        let header = mcap::records::MessageHeader {
            channel_id: seg.channels[topic_ix],
            sequence: seq as u32,
            log_time: time,
            publish_time: time,
        };
        match seg.mcap.write_to_known_channel(&header, data) {
            Ok(()) => self.unreported += 1,
            Err(e) => self.fail(e),
        }
    }

    /// Close the open segment, if any: its summary and footer make it a complete MCAP file.
    fn close_segment(&mut self) {
        let Some(mut seg) = self.current.take() else { return };
        let end = BTreeMap::from([
            ("next_seq".to_owned(), self.seq.to_string()),
            ("capped".to_owned(), self.capped.to_string()),
            ("dropped_cap".to_owned(), self.shared.dropped_cap.load(Ordering::Relaxed).to_string()),
        ]);
        let name = format!("{METADATA}.end");
        let result = seg
            .mcap
            .write_metadata(&mcap::records::Metadata { name, metadata: end })
            .and_then(|()| seg.mcap.finish().map(|_| ()));
        let result = result.map_err(|e| e.to_string()).and_then(|()| {
            let mut counted = seg.mcap.into_inner();
            counted.flush().map_err(|e| e.to_string())
        });
        let size = seg.size.load(Ordering::Relaxed);
        self.closed_bytes += size;
        self.sizes.insert(self.index, size);
        self.shared.bytes.fetch_add(size, Ordering::Relaxed);
        if let Err(e) = result {
            self.fail(e);
        }
    }
}

impl SegmentWriter {
    /// One segment's share of the byte cap: all of it for a recording that keeps its
    /// beginning; for a rolling one at most half, so that a run can be deleted while the next
    /// is written.
    fn segment_budget(&self, max_bytes: u64) -> u64 {
        let cap = if self.options.keep_last.is_some() { max_bytes / 2 } else { max_bytes };
        self.options.segment_bytes.min(cap)
    }

    /// Start a new run with `snapshot`: close the segment, open the next with the checkpoint
    /// first, and delete the runs no longer needed (module docs).
    fn start_run(&mut self, snapshot: &Snapshot) {
        let Some(window) = self.options.keep_last else { return };
        if self.shared.error.lock().is_ok_and(|e| e.is_some()) {
            return;
        }
        self.close_segment();
        self.capped = false;
        self.index += 1;
        let at = snapshot.at();
        self.runs.push_back(Run { first: self.index, start: at });
        let reach = ayllu_core::Duration::from_nanos(u64::try_from(window.as_nanos()).unwrap_or(u64::MAX));
        while self.runs.len() > 1 && self.runs.get(1).is_some_and(|r| r.start + reach <= at) {
            self.delete_oldest_run();
        }
        let budget = self.segment_budget(self.options.max_bytes);
        self.prune_for(budget);
        match self.open(self.index, budget) {
            Ok(seg) => {
                self.current = Some(seg);
                self.shared.segments.fetch_add(1, Ordering::Relaxed);
            }
            Err(e) => return self.fail(e),
        }
        let mut data = Vec::new();
        encode_checkpoint_into(self.seq, snapshot, &mut data);
        let Some(seg) = self.current.as_ref() else { return };
        if seg.size.load(Ordering::Relaxed) + data.len() as u64 + 64 > seg.budget {
            let budget = seg.budget;
            return self.fail(format!(
                "a checkpoint of {} bytes does not fit a segment of {budget} bytes: raise the recording's byte cap",
                data.len()
            ));
        }
        let Some(seg) = self.current.as_mut() else { return };
        let topic_ix = Topic::ALL.iter().position(|t| *t == Topic::Checkpoint).unwrap_or(0);
        let time = self.epoch_ns.saturating_add(at.as_nanos());
        let header = mcap::records::MessageHeader {
            channel_id: seg.channels[topic_ix],
            sequence: self.seq as u32,
            log_time: time,
            publish_time: time,
        };
        if let Err(e) = seg.mcap.write_to_known_channel(&header, &data) {
            self.fail(e);
        }
    }

    /// Delete runs, oldest first (never the newest), until `more` bytes fit under the cap.
    fn prune_for(&mut self, more: u64) {
        while self.options.keep_last.is_some()
            && self.runs.len() > 1
            && self.closed_bytes + more > self.options.max_bytes
        {
            self.delete_oldest_run();
        }
    }

    fn delete_oldest_run(&mut self) {
        let (Some(old), Some(next)) = (self.runs.pop_front(), self.runs.front().copied()) else { return };
        for n in old.first..next.first {
            if std::fs::remove_file(segment_path(&self.first, n)).is_ok() {
                self.shared.deleted.fetch_add(1, Ordering::Relaxed);
            }
            self.closed_bytes = self.closed_bytes.saturating_sub(self.sizes.remove(&n).unwrap_or(0));
        }
    }
}

/// The node's clock zero as Unix time: now minus the node's time.
fn epoch_ns(core: &NodeCore) -> u64 {
    let unix = SystemTime::now().duration_since(UNIX_EPOCH).map_or(0, |d| d.as_nanos() as u64);
    unix.saturating_sub(core.now().as_nanos())
}
