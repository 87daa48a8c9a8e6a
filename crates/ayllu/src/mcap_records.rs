//! The records of an MCAP file read from its bytes, for the two readers of files that come from
//! outside: flight recordings ([`crate::replay`]) and team recordings
//! ([`crate::team_recording`]).
//!
//! Why not the `mcap` crate's readers: in mcap 0.26 (the newest release when this was
//! written; the repository's newer code has the same lines) a record length near `u64::MAX`
//! overflows in the linear reader and panics (`linear_reader.rs:543`, "range start index 9
//! out of range"): its `ChunkFlattener` and `MessageStream` set no record length limit. Its
//! attachment parser slices out of range on an attachment shorter than its header, and its
//! string parser reserves the length a string declares (up to 4 GiB) before reading it. A
//! recording is a file from outside (a killed robot's, a copied one), so here every length is
//! checked against the bytes that are there before anything is sliced or reserved, and only
//! the records the two readers use are decoded: channels, messages, metadata, the data end
//! and the footer; a chunk's CRC, when the writer computed one, is checked before its records
//! are read (a damaged chunk is a [`Malformed`], not different values). Everything else
//! (schemas, indexes, attachments, statistics) is framed and skipped unread. The `mcap` crate
//! still writes the files.
//!
//! Promise: for any bytes, [`Records`] yields records or one [`Malformed`] and then stops;
//! it never panics, and allocates in proportion to the bytes there, never to what a length
//! field says.

use std::fmt;

use mcap::records::op;

/// One record a reader uses, borrowing from the file's bytes.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum McapRecord<'a> {
    /// A channel: its id and topic (its schema, encoding and metadata are not read).
    Channel {
        /// The channel id messages refer to.
        id: u16,
        /// Its topic.
        topic: &'a str,
    },
    /// A message.
    Message {
        /// The channel id.
        channel: u16,
        /// Its sequence number on the channel.
        sequence: u32,
        /// Its log time, nanoseconds.
        log_time: u64,
        /// Its payload.
        data: &'a [u8],
    },
    /// A metadata record: its name and its key-value pairs, in file order.
    Metadata {
        /// The record's name.
        name: &'a str,
        /// Its pairs.
        pairs: Vec<(&'a str, &'a str)>,
    },
    /// The end of the data section: the records after it are the summary's copies and indexes.
    DataEnd,
    /// The footer: the file's last record (only its end magic follows).
    Footer,
}

impl McapRecord<'_> {
    /// The value of `key` in a metadata record.
    pub(crate) fn get(&self, key: &str) -> Option<&str> {
        match self {
            McapRecord::Metadata { pairs, .. } => pairs.iter().find(|(k, _)| *k == key).map(|(_, v)| *v),
            _ => None,
        }
    }
}

/// Why the bytes stop being readable, and where.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct Malformed {
    /// The offset in the file of the record (or chunk) that could not be read.
    pub at: usize,
    /// What is wrong with it.
    pub what: String,
}

impl fmt::Display for Malformed {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "at byte {}: {}", self.at, self.what)
    }
}

impl std::error::Error for Malformed {}

/// The records of a file, in file order, chunks opened (only uncompressed chunks: Ayllu writes
/// no other, and this build has no decompressor). Ends after [`McapRecord::Footer`] or after
/// the first [`Malformed`] (bytes that end before the footer are one).
pub(crate) struct Records<'a> {
    file: Cursor<'a>,
    /// The records of the chunk being read, if any.
    chunk: Option<Cursor<'a>>,
    done: bool,
}

/// Bytes being read, with their offset in the file (for the errors).
struct Cursor<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Cursor<'a> {
    fn malformed(&self, what: impl Into<String>) -> Malformed {
        Malformed { at: self.at, what: what.into() }
    }

    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8], Malformed> {
        match self.bytes.split_at_checked(n) {
            Some((head, rest)) => {
                self.bytes = rest;
                self.at += n;
                Ok(head)
            }
            None => Err(self.malformed(format!("{what} needs {n} bytes, {} are left", self.bytes.len()))),
        }
    }

    fn array<const N: usize>(&mut self, what: &str) -> Result<[u8; N], Malformed> {
        let b = self.take(N, what)?;
        let mut a = [0u8; N];
        a.copy_from_slice(b);
        Ok(a)
    }

    fn u16(&mut self, what: &str) -> Result<u16, Malformed> {
        self.array(what).map(u16::from_le_bytes)
    }

    fn u32(&mut self, what: &str) -> Result<u32, Malformed> {
        self.array(what).map(u32::from_le_bytes)
    }

    fn u64(&mut self, what: &str) -> Result<u64, Malformed> {
        self.array(what).map(u64::from_le_bytes)
    }

    /// A length read from the file, checked against what is left.
    fn len(&mut self, declared: u64, what: &str) -> Result<&'a [u8], Malformed> {
        let left = self.bytes.len();
        match usize::try_from(declared) {
            Ok(n) if n <= left => self.take(n, what),
            _ => Err(self.malformed(format!("{what} of {declared} bytes, but {left} are left (cut short?)"))),
        }
    }

    /// An MCAP string: a `u32` length, then that many bytes of UTF-8.
    fn str(&mut self, what: &str) -> Result<&'a str, Malformed> {
        let n = self.u32(what)?;
        let at = self.at;
        let bytes = self.len(u64::from(n), what)?;
        std::str::from_utf8(bytes).map_err(|_| Malformed { at, what: format!("{what} is not UTF-8") })
    }

    /// One record's opcode and body.
    fn record(&mut self) -> Result<(u8, Cursor<'a>), Malformed> {
        let at = self.at;
        let [opcode] = self.array("a record's opcode")?;
        let len = self.u64("a record's length")?;
        let body = self.len(len, &format!("a record (opcode {opcode:#04x})")).map_err(|e| Malformed { at, ..e })?;
        Ok((opcode, Cursor { bytes: body, at: at + 9 }))
    }
}

/// The records of `bytes`, a whole MCAP file (or the start of one). Errors: no magic bytes.
pub(crate) fn records(bytes: &[u8]) -> Result<Records<'_>, Malformed> {
    match bytes.split_at_checked(mcap::MAGIC.len()) {
        Some((magic, rest)) if magic == mcap::MAGIC => {
            Ok(Records { file: Cursor { bytes: rest, at: magic.len() }, chunk: None, done: false })
        }
        _ => Err(Malformed { at: 0, what: "not an MCAP file (no magic bytes at its start)".into() }),
    }
}

impl<'a> Records<'a> {
    /// The next record a reader uses.
    fn next_record(&mut self) -> Result<McapRecord<'a>, Malformed> {
        loop {
            if let Some(chunk) = &mut self.chunk {
                if chunk.bytes.is_empty() {
                    self.chunk = None;
                    continue;
                }
                let (opcode, body) = chunk.record()?;
                if let Some(r) = decode(opcode, body)? {
                    return Ok(r);
                }
                continue;
            }
            if self.file.bytes.is_empty() {
                // A file ends with its footer (and the end magic): ending before it, at a
                // record's boundary, is still a file cut short.
                return Err(self.file.malformed("the file ends before its footer (cut short?)"));
            }
            let (opcode, mut body) = self.file.record()?;
            if opcode == op::CHUNK {
                self.chunk = Some(chunk_records(&mut body)?);
                continue;
            }
            if let Some(r) = decode(opcode, body)? {
                return Ok(r);
            }
        }
    }
}

impl<'a> Iterator for Records<'a> {
    type Item = Result<McapRecord<'a>, Malformed>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        let next = self.next_record();
        self.done = matches!(next, Err(_) | Ok(McapRecord::Footer));
        Some(next)
    }
}

/// A chunk record's body: its header checked, the records it holds.
fn chunk_records<'a>(body: &mut Cursor<'a>) -> Result<Cursor<'a>, Malformed> {
    let _start_time = body.u64("a chunk's start time")?;
    let _end_time = body.u64("a chunk's end time")?;
    let _uncompressed_size = body.u64("a chunk's uncompressed size")?;
    let crc = body.u32("a chunk's CRC")?;
    let compression = body.str("a chunk's compression")?;
    if !compression.is_empty() {
        return Err(body.malformed(format!(
            "a chunk compressed with `{compression}`: this build reads uncompressed chunks (the ones Ayllu writes)"
        )));
    }
    let size = body.u64("a chunk's records size")?;
    let at = body.at;
    // A chunk a killed writer left open has `!0` here, as in its record's length: checked
    // against the bytes that are there, it ends what can be read instead of reading past.
    let records = body.len(size, "a chunk's records")?;
    // The CRC-32 of the uncompressed records, 0 when the writer did not compute one (MCAP
    // spec, "Chunk"). Checked before any record of the chunk is read: a flipped byte in a
    // value would otherwise be read as a different value, not as damage.
    if crc != 0 {
        let computed = crc32fast::hash(records);
        if computed != crc {
            return Err(Malformed {
                at,
                what: format!(
                    "a chunk's records do not match its CRC (stored {crc:#010x}, computed {computed:#010x}): the file is damaged"
                ),
            });
        }
    }
    Ok(Cursor { bytes: records, at })
}

/// Decode a record the readers use; `None` for the kinds they skip.
fn decode(opcode: u8, mut body: Cursor<'_>) -> Result<Option<McapRecord<'_>>, Malformed> {
    Ok(Some(match opcode {
        op::CHANNEL => {
            let id = body.u16("a channel's id")?;
            let _schema = body.u16("a channel's schema id")?;
            let topic = body.str("a channel's topic")?;
            McapRecord::Channel { id, topic }
        }
        op::MESSAGE => {
            let channel = body.u16("a message's channel id")?;
            let sequence = body.u32("a message's sequence")?;
            let log_time = body.u64("a message's log time")?;
            let _publish_time = body.u64("a message's publish time")?;
            McapRecord::Message { channel, sequence, log_time, data: body.bytes }
        }
        op::METADATA => {
            let name = body.str("a metadata record's name")?;
            let size = body.u32("a metadata record's map size")?;
            let mut map = Cursor { at: body.at, bytes: body.len(u64::from(size), "a metadata record's map")? };
            let mut pairs = Vec::new();
            while !map.bytes.is_empty() {
                let k = map.str("a metadata key")?;
                let v = map.str("a metadata value")?;
                pairs.push((k, v));
            }
            McapRecord::Metadata { name, pairs }
        }
        op::DATA_END => McapRecord::DataEnd,
        op::FOOTER => McapRecord::Footer,
        _ => return Ok(None),
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn all(bytes: &[u8]) -> Vec<Result<McapRecord<'_>, Malformed>> {
        records(bytes).unwrap().collect()
    }

    #[test]
    fn a_length_near_u64_max_is_an_error_not_an_overflow() {
        let mut f = mcap::MAGIC.to_vec();
        f.extend([0xff; 100]);
        let r = all(&f);
        assert_eq!(r.len(), 1);
        let e = r[0].as_ref().unwrap_err();
        assert_eq!(e.at, 8);
        assert!(e.what.contains("18446744073709551615 bytes, but 91 are left"), "{e}");
    }

    #[test]
    fn no_magic_is_an_error() {
        assert!(records(b"").is_err());
        assert!(records(b"\x89MCAP0\r").is_err());
        assert!(records(b"hello, world, this is text").is_err());
        assert!(all(mcap::MAGIC)[0].as_ref().unwrap_err().what.contains("ends before its footer"));
    }

    #[test]
    fn a_string_longer_than_its_record_is_an_error() {
        // A channel record whose topic claims 4 GiB.
        let mut f = mcap::MAGIC.to_vec();
        let body = [&1u16.to_le_bytes()[..], &0u16.to_le_bytes(), &u32::MAX.to_le_bytes(), b"abc"].concat();
        f.push(op::CHANNEL);
        f.extend((body.len() as u64).to_le_bytes());
        f.extend(&body);
        let e = all(&f).remove(0).unwrap_err();
        assert!(e.what.contains("topic of 4294967295 bytes, but 3 are left"), "{e}");
    }

    /// A file of one uncompressed chunk holding `records`, with `crc` in its header.
    fn one_chunk(records: &[u8], crc: u32) -> Vec<u8> {
        let body = [
            &0u64.to_le_bytes()[..],
            &0u64.to_le_bytes(),
            &(records.len() as u64).to_le_bytes(),
            &crc.to_le_bytes(),
            &0u32.to_le_bytes(),
            &(records.len() as u64).to_le_bytes(),
            records,
        ]
        .concat();
        let mut f = mcap::MAGIC.to_vec();
        f.push(op::CHUNK);
        f.extend((body.len() as u64).to_le_bytes());
        f.extend(&body);
        f
    }

    #[test]
    fn a_chunk_whose_crc_does_not_match_its_records_is_refused() {
        // A channel record (id 1, topic "abc"), then the file ends (no footer).
        let channel = [&1u16.to_le_bytes()[..], &0u16.to_le_bytes(), &3u32.to_le_bytes(), b"abc"].concat();
        let records = [&[op::CHANNEL][..], &(channel.len() as u64).to_le_bytes(), &channel].concat();
        let crc = crc32fast::hash(&records);
        fn read(f: &[u8]) -> Result<McapRecord<'_>, String> {
            all(f).remove(0).map_err(|e| e.to_string())
        }
        // The right CRC, and 0 ("not computed", MCAP spec), read.
        assert_eq!(read(&one_chunk(&records, crc)), Ok(McapRecord::Channel { id: 1, topic: "abc" }));
        assert_eq!(read(&one_chunk(&records, 0)), Ok(McapRecord::Channel { id: 1, topic: "abc" }));
        // One flipped byte of the records (the topic's `b` to `c`), or a wrong CRC: refused
        // before any of its records is read, naming both CRCs.
        let mut flipped = one_chunk(&records, crc);
        let last = flipped.len() - 2;
        flipped[last] ^= 0x01;
        let e = read(&flipped).unwrap_err();
        assert_eq!(all(&flipped).len(), 1);
        assert!(e.starts_with("at byte 57: a chunk's records do not match its CRC (stored 0x"), "{e}");
        assert!(e.ends_with("): the file is damaged"), "{e}");
        let e = read(&one_chunk(&records, crc ^ 1)).unwrap_err();
        assert!(e.contains(&format!("stored {:#010x}, computed {crc:#010x}", crc ^ 1)), "{e}");
    }

    #[test]
    fn an_unclosed_chunk_is_an_error() {
        // What a killed writer leaves: the chunk's length and sizes still `!0`.
        let mut f = mcap::MAGIC.to_vec();
        f.push(op::CHUNK);
        f.extend(u64::MAX.to_le_bytes());
        f.extend([0u8; 40]);
        assert!(all(&f).remove(0).is_err());
    }
}
