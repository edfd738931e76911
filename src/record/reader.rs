//! The MCAP records of a recording, read from untrusted bytes: every length is checked against the
//! bytes that hold it before anything is sliced or allocated, so any file — cut short, with flipped
//! bytes, with forged lengths — gives its records or a [`Damage`] that says where and what is wrong,
//! never a panic or an allocation the file cannot account for.
//!
//! Bytes enter as one slice (the whole file); records leave through a callback in file order, the
//! records of each chunk in place of the chunk. Only what a recording needs is parsed (channels,
//! messages, attachments, the footer); other records are stepped over by their length. A compressed
//! chunk is decompressed by the `mcap` crate's sans-io reader with a record length limit of the
//! chunk's declared uncompressed size, which is first checked against [`MAX_COMPRESSION_RATIO`]
//! times its compressed size; a chunk's CRC is checked before any of its records is handed on.
//!
//! A file is whole only when every byte is accounted for: the data section's CRC (in the data end
//! record) covers the records outside chunks' data, the footer's summary CRC covers the summary
//! section (indexes, statistics) and the footer, and the footer is followed by the end magic and
//! nothing else. A file damaged only there still has all its messages; the damage is reported all
//! the same.

use mcap::records::op;
use mcap::sans_io::{LinearReadEvent, LinearReader, LinearReaderOptions};

/// The bytes every MCAP file starts with.
pub const MAGIC: &[u8; 8] = b"\x89MCAP0\r\n";

/// The largest expansion a chunk may declare (uncompressed bytes per compressed byte, beyond
/// [`RATIO_ALLOWANCE`]). palpa's recordings compress 5:1 to 10:1 (zstd); a declared size past this
/// bound is a damaged length, and it would otherwise be allocated before decompression fails.
pub const MAX_COMPRESSION_RATIO: u64 = 100;

/// Uncompressed bytes any chunk may declare whatever its compressed size (small chunks of very
/// regular messages can compress more than [`MAX_COMPRESSION_RATIO`]).
pub const RATIO_ALLOWANCE: u64 = 1 << 20;

/// Opcode and length in front of every record.
const RECORD_HEADER: usize = 9;

/// Where reading stopped and why.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("at byte {offset}: {problem}")]
pub struct Damage {
    /// Offset in the file of the record (or chunk) that cannot be read.
    pub offset: u64,
    /// What is wrong with it.
    pub problem: Problem,
}

/// What is wrong with a record.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum Problem {
    /// The file does not start with [`MAGIC`].
    #[error("not an MCAP file: it does not start with the 8 MCAP magic bytes")]
    BadMagic,
    /// Fewer than the 9 bytes of a record header are left.
    #[error("the file ends inside a record header (9 bytes needed, {available} left): cut short")]
    CutHeader {
        /// Bytes left in the file.
        available: u64,
    },
    /// A record is longer than what is left of the file.
    #[error(
        "{record} record of {length} bytes, but only {available} bytes follow: cut short, or a damaged length"
    )]
    CutRecord {
        /// Record type.
        record: &'static str,
        /// Its declared length.
        length: u64,
        /// Bytes left in the file after its header.
        available: u64,
    },
    /// A field does not fit in its record.
    #[error(
        "{record} record: `{field}` needs {needed} bytes, but only {available} are left in the record"
    )]
    Field {
        /// Record type.
        record: &'static str,
        /// Field name (as in the MCAP specification).
        field: &'static str,
        /// Bytes the field needs.
        needed: u64,
        /// Bytes left in the record.
        available: u64,
    },
    /// A text field is not UTF-8.
    #[error("{record} record: `{field}` is not UTF-8 text")]
    NotUtf8 {
        /// Record type.
        record: &'static str,
        /// Field name.
        field: &'static str,
    },
    /// A chunk declares an uncompressed size its compressed bytes cannot hold.
    #[error(
        "chunk declares {uncompressed} bytes uncompressed from {compressed} compressed, more than \
         {MAX_COMPRESSION_RATIO}:1 (plus {RATIO_ALLOWANCE} bytes): a damaged size"
    )]
    ImplausibleChunk {
        /// Declared uncompressed size.
        uncompressed: u64,
        /// Compressed size.
        compressed: u64,
    },
    /// A chunk's data cannot be decompressed or fails its CRC.
    #[error("chunk ({compression:?}, {compressed} bytes): {reason}")]
    ChunkData {
        /// Compression name (empty for none).
        compression: String,
        /// Compressed size.
        compressed: u64,
        /// What the decompressor or the CRC check said.
        reason: String,
    },
    /// A record inside a chunk is bad.
    #[error("record {index} of the chunk: {problem}")]
    InChunk {
        /// 0-based index of the record in the chunk.
        index: usize,
        /// What is wrong with it.
        problem: Box<Problem>,
    },
    /// An attachment's CRC does not match its bytes.
    #[error(
        "attachment {name:?}: CRC {saved:08x} recorded, {computed:08x} computed: damaged bytes"
    )]
    AttachmentCrc {
        /// Attachment name.
        name: String,
        /// CRC in the file.
        saved: u32,
        /// CRC of the bytes read.
        computed: u32,
    },
    /// A message refers to a channel no channel record declared.
    #[error("a message on channel {channel}, which no channel record declares")]
    UnknownChannel {
        /// The channel id.
        channel: u16,
    },
    /// The session's scene message cannot be decoded.
    #[error("the /palpa/scene message cannot be decoded: {reason}")]
    Scene {
        /// The protobuf decoder's message.
        reason: String,
    },
    /// No scene message before the end of what could be read.
    #[error("the recording has no /palpa/scene message")]
    NoScene,
    /// The data section's bytes do not match the CRC in the data end record.
    #[error(
        "data end record: data section CRC {saved:08x} recorded, {computed:08x} computed over bytes \
         0..{end}: damaged bytes outside the chunks' data (all messages were read)"
    )]
    DataCrc {
        /// CRC in the file.
        saved: u32,
        /// CRC of the bytes read.
        computed: u32,
        /// End of the data section (offset of the data end record).
        end: u64,
    },
    /// A footer without a data end record before it.
    #[error(
        "footer without a data end record before it: the end of the data section is damaged \
         (all messages were read)"
    )]
    NoDataEnd,
    /// The footer's summary start is not where the summary section starts.
    #[error(
        "footer: summary section recorded to start at byte {recorded}, but it starts at byte \
         {actual}: a damaged footer (all messages were read)"
    )]
    SummaryStart {
        /// `summary_start` in the footer (0: no summary section).
        recorded: u64,
        /// Where the summary section starts (0: it is empty).
        actual: u64,
    },
    /// The summary section and footer do not match the footer's CRC.
    #[error(
        "footer: summary CRC {saved:08x} recorded, {computed:08x} computed: damaged bytes in the \
         summary section (indexes, statistics) or the footer (all messages were read)"
    )]
    SummaryCrc {
        /// CRC in the file.
        saved: u32,
        /// CRC of the bytes read.
        computed: u32,
    },
    /// The footer is not followed by exactly the end magic.
    #[error(
        "the footer is not followed by exactly the 8 MCAP end magic bytes ({after} bytes follow \
         it): cut short or damaged (all messages were read)"
    )]
    EndMagic {
        /// Bytes after the footer record.
        after: u64,
    },
}

/// One record a recording is made of, borrowed from the file or from a decompressed chunk.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Item<'a> {
    /// A channel: its id and topic.
    Channel {
        /// Channel id.
        id: u16,
        /// Topic.
        topic: &'a str,
    },
    /// A message on a channel.
    Message {
        /// Channel id.
        channel_id: u16,
        /// Log time (ns).
        log_time: u64,
        /// Payload.
        data: &'a [u8],
    },
    /// An attachment, its CRC checked.
    Attachment {
        /// Name.
        name: &'a str,
        /// Bytes.
        data: &'a [u8],
    },
    /// The footer: the file ended properly.
    Footer,
}

/// Reads every record of an MCAP file in order and hands channels, messages, attachments and the
/// footer to `visit`; stops at the footer (the records of the summary section before it are read
/// like any other). The data section's CRC is checked at the data end record; the footer is handed
/// on only once the summary CRC has been checked and the end magic found after it. The first bad
/// record, or the first problem `visit` returns, ends the reading with its offset.
pub fn read_records(
    bytes: &[u8],
    mut visit: impl FnMut(Item<'_>) -> Result<(), Problem>,
) -> Result<(), Damage> {
    if bytes.len() < MAGIC.len() || bytes[..MAGIC.len()] != MAGIC[..] {
        return Err(Damage {
            offset: 0,
            problem: Problem::BadMagic,
        });
    }
    let mut at = MAGIC.len();
    // Where the summary section starts: just after the data end record, once it is read.
    let mut summary_start = None;
    while at < bytes.len() {
        let damage = |problem| Damage {
            offset: at as u64,
            problem,
        };
        let record = &bytes[at..];
        let (opcode, body) = split_record(record).map_err(damage)?;
        let end = at + RECORD_HEADER + body.len();
        let result = match opcode {
            op::CHUNK => read_chunk(&record[..RECORD_HEADER + body.len()], body, &mut visit),
            op::DATA_END => {
                summary_start = Some(end);
                check_data_end(body, &bytes[..at])
            }
            op::FOOTER => {
                let start = summary_start.ok_or(Problem::NoDataEnd).map_err(damage)?;
                return check_footer(bytes, start, at, body)
                    .and_then(|()| visit(Item::Footer))
                    .map_err(damage);
            }
            _ => read_record(opcode, body, &mut visit),
        };
        result.map_err(damage)?;
        at = end;
    }
    Ok(())
}

/// The data end record's CRC (0: none recorded) against the data section before it.
fn check_data_end(body: &[u8], data: &[u8]) -> Result<(), Problem> {
    let saved = Fields::new(body, "data end").u32("data_section_crc")?;
    let computed = crc32(data);
    if saved != 0 && saved != computed {
        return Err(Problem::DataCrc {
            saved,
            computed,
            end: data.len() as u64,
        });
    }
    Ok(())
}

/// The footer at `at` (its body `body`), the summary section between `summary_start` and it: the
/// footer's summary start, its summary CRC (0: none recorded; it covers the summary section and the
/// footer up to the CRC) and the end magic after it, with nothing more.
fn check_footer(bytes: &[u8], summary_start: usize, at: usize, body: &[u8]) -> Result<(), Problem> {
    let mut f = Fields::new(body, "footer");
    let recorded = f.u64("summary_start")?;
    let _summary_offset_start = f.u64("summary_offset_start")?;
    let covered = at + RECORD_HEADER + (body.len() - f.rest.len());
    let saved = f.u32("summary_crc")?;
    // An empty summary section is recorded as 0.
    let actual = if summary_start < at { summary_start } else { 0 };
    if recorded != actual as u64 {
        return Err(Problem::SummaryStart {
            recorded,
            actual: actual as u64,
        });
    }
    let computed = crc32(&bytes[summary_start..covered]);
    if saved != 0 && saved != computed {
        return Err(Problem::SummaryCrc { saved, computed });
    }
    let after = &bytes[at + RECORD_HEADER + body.len()..];
    if after != &MAGIC[..] {
        return Err(Problem::EndMagic {
            after: after.len() as u64,
        });
    }
    Ok(())
}

/// The opcode and body of the record at the start of `rest`.
fn split_record(rest: &[u8]) -> Result<(u8, &[u8]), Problem> {
    let Some((header, after)) = rest.split_first_chunk::<RECORD_HEADER>() else {
        return Err(Problem::CutHeader {
            available: rest.len() as u64,
        });
    };
    let opcode = header[0];
    let mut length = [0u8; 8];
    length.copy_from_slice(&header[1..]);
    let length = u64::from_le_bytes(length);
    if length > after.len() as u64 {
        return Err(Problem::CutRecord {
            record: record_name(opcode),
            length,
            available: after.len() as u64,
        });
    }
    Ok((opcode, &after[..length as usize]))
}

/// The MCAP name of a record type.
fn record_name(opcode: u8) -> &'static str {
    match opcode {
        op::HEADER => "header",
        op::FOOTER => "footer",
        op::SCHEMA => "schema",
        op::CHANNEL => "channel",
        op::MESSAGE => "message",
        op::CHUNK => "chunk",
        op::MESSAGE_INDEX => "message index",
        op::CHUNK_INDEX => "chunk index",
        op::ATTACHMENT => "attachment",
        op::ATTACHMENT_INDEX => "attachment index",
        op::STATISTICS => "statistics",
        op::METADATA => "metadata",
        op::METADATA_INDEX => "metadata index",
        op::SUMMARY_OFFSET => "summary offset",
        op::DATA_END => "data end",
        _ => "unknown",
    }
}

/// The fields of one record, read front to back, each checked against what is left.
struct Fields<'a> {
    rest: &'a [u8],
    record: &'static str,
}

impl<'a> Fields<'a> {
    fn new(body: &'a [u8], record: &'static str) -> Self {
        Self { rest: body, record }
    }

    fn take(&mut self, needed: u64, field: &'static str) -> Result<&'a [u8], Problem> {
        if needed > self.rest.len() as u64 {
            return Err(Problem::Field {
                record: self.record,
                field,
                needed,
                available: self.rest.len() as u64,
            });
        }
        let (taken, rest) = self.rest.split_at(needed as usize);
        self.rest = rest;
        Ok(taken)
    }

    fn array<const N: usize>(&mut self, field: &'static str) -> Result<[u8; N], Problem> {
        let mut a = [0u8; N];
        a.copy_from_slice(self.take(N as u64, field)?);
        Ok(a)
    }

    fn u16(&mut self, field: &'static str) -> Result<u16, Problem> {
        self.array(field).map(u16::from_le_bytes)
    }

    fn u32(&mut self, field: &'static str) -> Result<u32, Problem> {
        self.array(field).map(u32::from_le_bytes)
    }

    fn u64(&mut self, field: &'static str) -> Result<u64, Problem> {
        self.array(field).map(u64::from_le_bytes)
    }

    /// A string: u32 byte length, then UTF-8 bytes.
    fn string(&mut self, field: &'static str) -> Result<&'a str, Problem> {
        let length = self.u32(field)?;
        let bytes = self.take(u64::from(length), field)?;
        std::str::from_utf8(bytes).map_err(|_| Problem::NotUtf8 {
            record: self.record,
            field,
        })
    }
}

/// A record outside chunks or inside one (chunks and footers inside a chunk are not valid MCAP and
/// are stepped over like unknown records).
fn read_record(
    opcode: u8,
    body: &[u8],
    visit: &mut impl FnMut(Item<'_>) -> Result<(), Problem>,
) -> Result<(), Problem> {
    match opcode {
        op::CHANNEL => {
            let mut f = Fields::new(body, "channel");
            let id = f.u16("id")?;
            let _schema_id = f.u16("schema_id")?;
            let topic = f.string("topic")?;
            visit(Item::Channel { id, topic })
        }
        op::MESSAGE => {
            let mut f = Fields::new(body, "message");
            let channel_id = f.u16("channel_id")?;
            let _sequence = f.u32("sequence")?;
            let log_time = f.u64("log_time")?;
            let _publish_time = f.u64("publish_time")?;
            visit(Item::Message {
                channel_id,
                log_time,
                data: f.rest,
            })
        }
        op::ATTACHMENT => {
            let mut f = Fields::new(body, "attachment");
            let _log_time = f.u64("log_time")?;
            let _create_time = f.u64("create_time")?;
            let name = f.string("name")?;
            let _media_type = f.string("media_type")?;
            let data_len = f.u64("data_len")?;
            let data = f.take(data_len, "data")?;
            let covered = body.len() - f.rest.len();
            let saved = f.u32("crc")?;
            let computed = crc32(&body[..covered]);
            if saved != 0 && saved != computed {
                return Err(Problem::AttachmentCrc {
                    name: name.to_string(),
                    saved,
                    computed,
                });
            }
            visit(Item::Attachment { name, data })
        }
        _ => Ok(()),
    }
}

/// A chunk (`record` is the whole record, header included; `body` its body): its header checked,
/// its data decompressed within the declared size and CRC-checked, its records handed on.
fn read_chunk(
    record: &[u8],
    body: &[u8],
    visit: &mut impl FnMut(Item<'_>) -> Result<(), Problem>,
) -> Result<(), Problem> {
    let mut f = Fields::new(body, "chunk");
    let _start = f.u64("message_start_time")?;
    let _end = f.u64("message_end_time")?;
    let uncompressed = f.u64("uncompressed_size")?;
    let crc = f.u32("uncompressed_crc")?;
    let compression = f.string("compression")?;
    let compressed = f.u64("compressed_size")?;
    let records = f.take(compressed, "records")?;
    let data_problem = |reason: String| Problem::ChunkData {
        compression: compression.to_string(),
        compressed,
        reason,
    };
    if compression.is_empty() {
        // Uncompressed: the records are in the file already; walk them here.
        if uncompressed != compressed {
            return Err(data_problem(format!(
                "uncompressed chunk declares {uncompressed} bytes but holds {compressed}"
            )));
        }
        let computed = crc32(records);
        if crc != 0 && crc != computed {
            return Err(data_problem(format!(
                "CRC {crc:08x} recorded, {computed:08x} computed: damaged bytes"
            )));
        }
        let mut rest = records;
        let mut index = 0;
        while !rest.is_empty() {
            let in_chunk = |problem| Problem::InChunk {
                index,
                problem: Box::new(problem),
            };
            let (opcode, inner) = split_record(rest).map_err(in_chunk)?;
            read_record(opcode, inner, visit).map_err(in_chunk)?;
            rest = &rest[RECORD_HEADER + inner.len()..];
            index += 1;
        }
        return Ok(());
    }
    if uncompressed > compressed.saturating_mul(MAX_COMPRESSION_RATIO) + RATIO_ALLOWANCE {
        return Err(Problem::ImplausibleChunk {
            uncompressed,
            compressed,
        });
    }
    // No record in the chunk can be longer than the chunk, and the whole uncompressed chunk is held
    // at most once (for its CRC) — both bounded by the size just checked.
    let limit = usize::try_from(uncompressed.max(record.len() as u64))
        .map_err(|_| data_problem("larger than this machine's address space".into()))?;
    let mut reader = LinearReader::new_with_options(
        LinearReaderOptions::default()
            .with_skip_start_magic(true)
            .with_skip_end_magic(true)
            .with_validate_chunk_crcs(true)
            .with_prevalidate_chunk_crcs(true)
            .with_record_length_limit(limit),
    );
    let mut input = record;
    let mut index = 0;
    while let Some(event) = reader.next_event() {
        match event.map_err(|e| data_problem(e.to_string()))? {
            LinearReadEvent::ReadRequest(wanted) => {
                let n = wanted.min(input.len());
                reader.insert(n).copy_from_slice(&input[..n]);
                reader.notify_read(n);
                input = &input[n..];
            }
            LinearReadEvent::Record { data, opcode } => {
                read_record(opcode, data, visit).map_err(|problem| Problem::InChunk {
                    index,
                    problem: Box::new(problem),
                })?;
                index += 1;
            }
        }
    }
    Ok(())
}

/// CRC-32 (IEEE, reflected), as MCAP uses for chunks and attachments.
fn crc32(bytes: &[u8]) -> u32 {
    const TABLE: [u32; 256] = {
        let mut table = [0u32; 256];
        let mut i = 0;
        while i < 256 {
            let mut c = i as u32;
            let mut k = 0;
            while k < 8 {
                c = if c & 1 != 0 {
                    0xedb8_8320 ^ (c >> 1)
                } else {
                    c >> 1
                };
                k += 1;
            }
            table[i] = c;
            i += 1;
        }
        table
    };
    let mut c = !0u32;
    for &b in bytes {
        c = TABLE[((c ^ b as u32) & 0xff) as usize] ^ (c >> 8);
    }
    !c
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc32_matches_the_standard_check_value() {
        assert_eq!(crc32(b"123456789"), 0xcbf4_3926);
    }

    #[test]
    fn a_chunk_claiming_a_huge_size_is_refused_before_allocation() {
        // A zstd chunk of 4 compressed bytes that claims 5e18 uncompressed.
        let mut body = Vec::new();
        body.extend_from_slice(&0u64.to_le_bytes());
        body.extend_from_slice(&0u64.to_le_bytes());
        body.extend_from_slice(&5_000_470_302_814_682_325u64.to_le_bytes());
        body.extend_from_slice(&0u32.to_le_bytes());
        body.extend_from_slice(&4u32.to_le_bytes());
        body.extend_from_slice(b"zstd");
        body.extend_from_slice(&4u64.to_le_bytes());
        body.extend_from_slice(&[0x28, 0xb5, 0x2f, 0xfd]);
        let mut file = MAGIC.to_vec();
        file.push(op::CHUNK);
        file.extend_from_slice(&(body.len() as u64).to_le_bytes());
        file.extend_from_slice(&body);
        let damage = read_records(&file, |_| Ok(())).unwrap_err();
        assert_eq!(damage.offset, 8);
        assert!(matches!(
            damage.problem,
            Problem::ImplausibleChunk { compressed: 4, .. }
        ));
    }
}
