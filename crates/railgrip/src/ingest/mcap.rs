//! MCAP logs: topic and field per signal from `[ingest.mcap]` (several signals may share a
//! topic with different fields). Channels may run at different rates; unrelated topics are
//! skipped without decoding. Chunk CRCs are checked. Message encodings: `json` (data-contract.md,
//! top-level number fields), `protobuf` (FileDescriptorSet schemas, [`super::protobuf`]) and
//! `cdr` with `ros2msg` schemas (ROS 2, [`super::ros2`]); field paths reach into nested
//! messages (`twist.linear.x`) and arrays (`velocity[2]`).

use std::collections::{BTreeMap, HashMap};
use std::fmt;
use std::path::Path;
use std::sync::Arc;

use std::io::Read;

use ::mcap::records::{MessageHeader, Record};
use ::mcap::sans_io::{LinearReadEvent, LinearReader, LinearReaderOptions};
use ::mcap::McapError;
use serde::de::{DeserializeSeed, Deserializer, IgnoredAny, MapAccess, Visitor};

use super::{DecodeError, IngestError, Location, Locator, RawChannel, Warning, WarningKind};
use crate::config::IngestConfig;
use crate::format::{RunMetadata, Signal, MCAP_MESSAGE_ENCODING, MCAP_METADATA_NAME};

/// The hint for a mapped field path that does not parse or does not fit the channel's schema.
const MAP_HINT: &str = "set `field` of the signal in [ingest.mcap] of the pipeline to one of the fields listed (a path such as twist.linear.x, [k] for an array element)";

/// Largest decompressed chunk accepted when the file itself is smaller, bytes.
const MAX_CHUNK_BYTES: usize = 256 << 20;

/// The message encodings railgrip reads, for error messages.
pub const SUPPORTED_ENCODINGS: &str =
    "\"json\", \"protobuf\" (protobuf schema) and \"cdr\" (ros2msg schema)";

/// Values read from one message: slots 0..10 for the mapped fields (nine signals at most), then the header stamp's
/// seconds and nanoseconds ([`STAMP_SLOTS`]).
pub(super) type Found = [Option<f64>; 12];
pub(super) const STAMP_SLOTS: (usize, usize) = (10, 11);

/// A field path of the mapping: names separated by `.`, each with an optional `[index]`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FieldPath {
    pub text: String,
    pub segments: Vec<(String, Option<usize>)>,
}

impl FieldPath {
    /// Parses `a.b[2].c`.
    pub fn parse(text: &str) -> Result<FieldPath, DecodeError> {
        let mut segments = Vec::new();
        for part in text.split('.') {
            let (name, index) = match part.find('[') {
                None => (part, None),
                Some(open) => {
                    let inner = part[open + 1..].strip_suffix(']').ok_or_else(|| {
                        DecodeError::PathUnclosedIndex {
                            path: text.to_string(),
                            part: part.to_string(),
                        }
                    })?;
                    let k: usize = inner
                        .parse()
                        .map_err(|_| DecodeError::PathIndexNotANumber {
                            path: text.to_string(),
                            index: inner.to_string(),
                        })?;
                    (&part[..open], Some(k))
                }
            };
            if name.is_empty() {
                return Err(DecodeError::PathEmptyName {
                    path: text.to_string(),
                });
            }
            segments.push((name.to_string(), index));
        }
        Ok(FieldPath {
            text: text.to_string(),
            segments,
        })
    }
}

/// The decoder of one channel's payloads, outside an MCAP file: for tests, fuzzing and the
/// benchmark's bare decode. `encoding` is the channel's message encoding, the schema as the
/// file stores it; `fields` the mapped paths.
pub struct MessageDecoder {
    decoder: Decoder,
    fields: usize,
}

impl MessageDecoder {
    pub fn new(
        encoding: &str,
        schema_name: &str,
        schema_data: &[u8],
        fields: &[&str],
        header_time: bool,
    ) -> Result<MessageDecoder, DecodeError> {
        let paths = fields
            .iter()
            .map(|f| FieldPath::parse(f))
            .collect::<Result<Vec<_>, _>>()?;
        if paths.len() > STAMP_SLOTS.0 {
            return Err(DecodeError::TooManyFields { max: STAMP_SLOTS.0 });
        }
        let decoder = match encoding {
            MCAP_MESSAGE_ENCODING => Decoder::Json,
            "protobuf" => Decoder::Protobuf(super::protobuf::Decoder::new(
                schema_name,
                schema_data,
                &paths,
                header_time,
            )?),
            "cdr" => Decoder::Ros2(super::ros2::Decoder::new(
                schema_name,
                schema_data,
                &paths,
                header_time,
            )?),
            e => {
                return Err(DecodeError::UnknownEncoding {
                    encoding: e.to_string(),
                    supported: SUPPORTED_ENCODINGS,
                })
            }
        };
        Ok(MessageDecoder {
            decoder,
            fields: fields.len(),
        })
    }

    /// The mapped fields' values of one payload, then the stamp (seconds, nanoseconds).
    pub fn extract(
        &self,
        payload: &[u8],
        json_names: &[&str],
    ) -> Result<Vec<Option<f64>>, DecodeError> {
        let mut found: Found = [None; 12];
        match &self.decoder {
            Decoder::Json => extract(payload, json_names, &mut found)?,
            Decoder::Protobuf(p) => p.extract(payload, &mut found)?,
            Decoder::Ros2(r) => r.extract(payload, &mut found)?,
        }
        let mut v = found[..self.fields].to_vec();
        v.extend([found[STAMP_SLOTS.0], found[STAMP_SLOTS.1]]);
        Ok(v)
    }

    /// The whole message decoded by the underlying decoder (prost-reflect's `DynamicMessage`,
    /// every CDR field, serde_json's `Value`): the "bare decode" of the ingest benchmark.
    /// Returns a count of what was decoded.
    pub fn decode_whole(&self, payload: &[u8]) -> Result<usize, DecodeError> {
        match &self.decoder {
            Decoder::Json => serde_json::from_slice::<serde_json::Value>(payload)
                .map(|v| v.as_object().map_or(0, |o| o.len()))
                .map_err(|source| DecodeError::Json { source }),
            Decoder::Protobuf(p) => p.decode_dynamic(payload).map(|m| m.fields().count()),
            Decoder::Ros2(r) => r.decode_all(payload),
        }
    }
}

/// How one channel's payloads are read.
enum Decoder {
    Json,
    Protobuf(super::protobuf::Decoder),
    Ros2(super::ros2::Decoder),
}

impl Decoder {
    fn name(&self) -> &'static str {
        match self {
            Decoder::Json => "JSON",
            Decoder::Protobuf(_) => "protobuf",
            Decoder::Ros2(_) => "CDR",
        }
    }
}

pub(super) struct McapRead {
    pub channels: Vec<RawChannel>,
    pub metadata: RunMetadata,
    /// Log time of t = 0 s: the first message of a mapped topic in the file, ns.
    pub t0_ns: u64,
    pub warnings: Vec<Warning>,
}

/// What a channel id maps to: the signals read from it and their JSON fields.
#[derive(Clone)]
enum Slot {
    Unseen,
    Ignored { channel: u16 },
    Read { topic_index: usize, decoder: usize },
}

struct TopicPlan {
    topic: String,
    /// (signal index, field name) pairs read from this topic.
    fields: Vec<(usize, String)>,
    /// Message count of this topic (also the index of the next message).
    messages: usize,
    seen_channel: bool,
    /// Times from the messages' header stamps instead of the log time.
    header_time: bool,
}

fn read_error(path: &Path, messages: usize, source: McapError) -> IngestError {
    let (what, hint) = match &source {
        McapError::BadChunkCrc { .. } | McapError::BadDataCrc { .. } | McapError::BadSummaryCrc { .. } => (
            "CRC mismatch",
            "the file is corrupted; copy it again from the logger",
        ),
        McapError::RecordTooLarge { .. } | McapError::ChunkTooLarge(_) | McapError::ChunkBufferTooLarge(_) => (
            "record larger than the file allows",
            "a length field is corrupt (or the chunk is a decompression bomb); copy the file again from the logger",
        ),
        McapError::UnexpectedEof | McapError::UnexpectedEoc | McapError::BadFooter => (
            "truncated file",
            "the recording was cut off before it was closed; `mcap recover` can rebuild a readable file",
        ),
        McapError::BadMagic => (
            "bad end magic",
            "the recording was cut off before it was closed; `mcap recover` can rebuild a readable file",
        ),
        _ => ("unreadable record", "the file is damaged or not a valid MCAP; check it with `mcap doctor`"),
    };
    IngestError::McapRead {
        path: path.to_path_buf(),
        messages,
        what,
        hint,
        source,
    }
}

/// Reads an MCAP log: one streaming pass collects the mapped topics' messages, then every
/// mapped topic is checked, each topic ordered by log time, and the channels built.
pub(super) fn read(src: &super::LogSource, cfg: &IngestConfig) -> Result<McapRead, IngestError> {
    let path = src.name();
    let file = src.open().map_err(|e| IngestError::Io {
        path: path.to_path_buf(),
        source: e,
    })?;
    let mut r = Reader::new(path, cfg);
    r.stream(file, src.len().unwrap_or(0) as usize)?;
    r.check_topics()?;
    let orders = r.order_by_time()?;
    r.finish(cfg, &orders)
}

/// What one pass over an MCAP log collects.
struct Reader<'a> {
    path: &'a Path,
    /// Topics to read, the signals and JSON fields of each, and the topic of each name.
    topics: Vec<TopicPlan>,
    topic_index: HashMap<String, usize>,
    field_names: Vec<Vec<String>>,
    /// Times are kept as f64 seconds after `t_ref` (the first mapped message's log time):
    /// exact for offsets below 2^53 ns (104 days). Per topic.
    t_ref: Option<u64>,
    times: Vec<Vec<f64>>,
    /// Values per signal, in [`Signal::ALL`] order.
    values: Vec<Vec<f64>>,
    /// Message counts of unmapped topics (for the missing-topic message).
    present: BTreeMap<String, usize>,
    slots: Vec<Slot>,
    /// Channel id → (topic, message encoding, schema id).
    channel_topics: HashMap<u16, (String, String, u16)>,
    /// Schema id → (name, encoding, data).
    schemas: HashMap<u16, (String, String, Vec<u8>)>,
    decoders: Vec<Decoder>,
    run_metadata: Option<BTreeMap<String, String>>,
    /// Messages seen so far (all topics).
    total: usize,
}

impl<'a> Reader<'a> {
    /// The plan: topics to read and which fields of each.
    fn new(path: &'a Path, cfg: &IngestConfig) -> Reader<'a> {
        let mut topics: Vec<TopicPlan> = Vec::new();
        let mut topic_index: HashMap<String, usize> = HashMap::new();
        for s in Signal::ALL {
            let m = cfg.mcap_field(s);
            let t = *topic_index.entry(m.topic.clone()).or_insert_with(|| {
                topics.push(TopicPlan {
                    topic: m.topic.clone(),
                    fields: Vec::new(),
                    messages: 0,
                    seen_channel: false,
                    header_time: m.header_time,
                });
                topics.len() - 1
            });
            topics[t].header_time |= m.header_time;
            topics[t].fields.push((s.index(), m.field.clone()));
        }
        let field_names = topics
            .iter()
            .map(|p| p.fields.iter().map(|(_, f)| f.clone()).collect())
            .collect();
        Reader {
            path,
            times: vec![Vec::new(); topics.len()],
            topics,
            topic_index,
            field_names,
            t_ref: None,
            values: vec![Vec::new(); 9],
            present: BTreeMap::new(),
            slots: Vec::new(),
            channel_topics: HashMap::new(),
            schemas: HashMap::new(),
            decoders: Vec::new(),
            run_metadata: None,
            total: 0,
        }
    }

    /// One streaming pass over the file (no whole-file buffer): channel records, messages
    /// (chunks decompressed and CRC-checked by the reader) and the metadata record. Every
    /// record and decompressed chunk is bounded: no record is longer than the file, and a
    /// chunk decompresses to at most max(file size, 256 MiB), so a corrupt length or a
    /// decompression bomb is an error, not an allocation failure.
    fn stream(&mut self, mut file: impl Read, file_len: usize) -> Result<(), IngestError> {
        let limit = file_len.max(MAX_CHUNK_BYTES);
        let options = LinearReaderOptions::default()
            .with_prevalidate_chunk_crcs(true)
            .with_record_length_limit(limit);
        let mut reader = LinearReader::new_with_options(options);
        while let Some(event) = reader.next_event() {
            match event.map_err(|e| read_error(self.path, self.total, e))? {
                LinearReadEvent::ReadRequest(need) => {
                    if need > limit {
                        return Err(read_error(
                            self.path,
                            self.total,
                            McapError::RecordTooLarge {
                                opcode: 0,
                                len: need as u64,
                            },
                        ));
                    }
                    let n = loop {
                        match file.read(reader.insert(need)) {
                            Ok(n) => break n,
                            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                            Err(e) => {
                                return Err(IngestError::Io {
                                    path: self.path.to_path_buf(),
                                    source: e,
                                })
                            }
                        }
                    };
                    reader.notify_read(n);
                }
                LinearReadEvent::Record { opcode, data } => self.record(opcode, data)?,
            }
        }
        // Growth by doubling leaves up to 2x capacity: give it back before resampling allocates.
        self.times
            .iter_mut()
            .chain(self.values.iter_mut())
            .for_each(|v| v.shrink_to_fit());
        Ok(())
    }

    fn record(&mut self, opcode: u8, data: &[u8]) -> Result<(), IngestError> {
        let record =
            ::mcap::parse_record(opcode, data).map_err(|e| read_error(self.path, self.total, e))?;
        match record {
            Record::Schema { header, data } if header.id != 0 => {
                self.schemas
                    .insert(header.id, (header.name, header.encoding, data.into_owned()));
            }
            Record::Channel(c) => {
                if let Some(&t) = self.topic_index.get(&c.topic) {
                    self.topics[t].seen_channel = true;
                }
                self.channel_topics
                    .insert(c.id, (c.topic, c.message_encoding, c.schema_id));
            }
            Record::Metadata(m) if m.name == MCAP_METADATA_NAME && self.run_metadata.is_none() => {
                self.run_metadata = Some(m.metadata);
            }
            Record::Message { header, data } => {
                self.total += 1;
                if let Some((t, d)) = self.topic_of(&header)? {
                    self.message(t, d, &header, &data)?;
                }
            }
            _ => {}
        }
        Ok(())
    }

    /// The mapped topic a message belongs to (None for unrelated topics, which are only
    /// counted); its channel's encoding is checked the first time.
    fn topic_of(&mut self, header: &MessageHeader) -> Result<Option<(usize, usize)>, IngestError> {
        let id = header.channel_id as usize;
        if id >= self.slots.len() {
            self.slots.resize(id + 1, Slot::Unseen);
        }
        if let Slot::Unseen = self.slots[id] {
            let (topic, encoding, schema_id) =
                self.channel_topics.get(&header.channel_id).ok_or_else(|| {
                    read_error(
                        self.path,
                        self.total,
                        McapError::UnknownChannel(header.sequence, header.channel_id),
                    )
                })?;
            self.slots[id] = match self.topic_index.get(topic) {
                None => Slot::Ignored {
                    channel: header.channel_id,
                },
                Some(&t) => {
                    let d = self.decoder(t, topic, encoding, *schema_id)?;
                    self.decoders.push(d);
                    Slot::Read {
                        topic_index: t,
                        decoder: self.decoders.len() - 1,
                    }
                }
            };
        }
        match self.slots[id] {
            Slot::Read {
                topic_index,
                decoder,
            } => Ok(Some((topic_index, decoder))),
            Slot::Ignored { channel } => {
                // Counting unrelated topics is cheap and helps the missing-topic message.
                if let Some((topic, _, _)) = self.channel_topics.get(&channel) {
                    if self.present.len() < 200 || self.present.contains_key(topic) {
                        *self.present.entry(topic.clone()).or_default() += 1;
                    }
                }
                Ok(None)
            }
            Slot::Unseen => unreachable!("resolved above"),
        }
    }

    /// The decoder of a channel on mapped topic `t` with `encoding` and schema `schema_id`.
    fn decoder(
        &self,
        t: usize,
        topic: &str,
        encoding: &str,
        schema_id: u16,
    ) -> Result<Decoder, IngestError> {
        let plan = &self.topics[t];
        let schema_error = |what: String, hint: &str| IngestError::McapSchema {
            path: self.path.to_path_buf(),
            topic: topic.to_string(),
            what,
            hint: hint.to_string(),
        };
        let schema = |want: &str| -> Result<&(String, String, Vec<u8>), IngestError> {
            let s = self.schemas.get(&schema_id).ok_or_else(|| {
                schema_error(
                    format!("a {encoding} channel needs a schema, but its schema id {schema_id} names none in the file"),
                    "the file is damaged or was written without schemas; re-record it",
                )
            })?;
            if s.1 != want {
                return Err(schema_error(
                    format!(
                        "message encoding {encoding:?} with schema encoding {:?} (schema {}); railgrip reads {encoding:?} messages with {want:?} schemas",
                        s.1, s.0
                    ),
                    if s.1 == "ros2idl" {
                        "record with .msg definitions (ros2msg), which rosbag2 writes by default"
                    } else {
                        "re-record the channel with a supported schema encoding"
                    },
                ));
            }
            Ok(s)
        };
        let paths = || -> Result<Vec<FieldPath>, IngestError> {
            plan.fields
                .iter()
                .map(|(_, f)| {
                    FieldPath::parse(f).map_err(|source| IngestError::McapFieldPath {
                        path: self.path.to_path_buf(),
                        topic: topic.to_string(),
                        hint: MAP_HINT,
                        source: Box::new(source),
                    })
                })
                .collect()
        };
        let compile_error = |schema_encoding: &'static str, schema: &str, source: DecodeError| {
            IngestError::McapDecoder {
                path: self.path.to_path_buf(),
                topic: topic.to_string(),
                schema_encoding,
                schema: schema.to_string(),
                hint: MAP_HINT,
                source: Box::new(source),
            }
        };
        match encoding {
            MCAP_MESSAGE_ENCODING => {
                if plan.header_time {
                    return Err(schema_error(
                        "time = \"header\" is set, but the channel is JSON, whose messages carry no typed header stamp".into(),
                        "remove time = \"header\" for this topic (the log time is used)",
                    ));
                }
                Ok(Decoder::Json)
            }
            "protobuf" => {
                let (name, _, data) = schema("protobuf")?;
                super::protobuf::Decoder::new(name, data, &paths()?, plan.header_time)
                    .map(Decoder::Protobuf)
                    .map_err(|e| compile_error("protobuf", name, e))
            }
            "cdr" => {
                let (name, _, data) = schema("ros2msg")?;
                super::ros2::Decoder::new(name, data, &paths()?, plan.header_time)
                    .map(Decoder::Ros2)
                    .map_err(|e| compile_error("ros2msg", name, e))
            }
            _ => Err(IngestError::McapEncoding {
                path: self.path.to_path_buf(),
                topic: topic.to_string(),
                encoding: encoding.to_string(),
                supported: SUPPORTED_ENCODINGS,
            }),
        }
    }

    /// Extracts the mapped fields of one message of topic `t`, read by decoder `d`.
    fn message(
        &mut self,
        t: usize,
        d: usize,
        header: &MessageHeader,
        payload: &[u8],
    ) -> Result<(), IngestError> {
        let plan = &mut self.topics[t];
        let names = &self.field_names[t];
        let index = plan.messages;
        plan.messages += 1;
        let path = self.path;
        let location = || Location::Mcap {
            topic: plan.topic.clone(),
            message: index,
            log_time_ns: header.log_time,
        };
        let bad = |what: String, hint: String| IngestError::McapBadMessage {
            path: path.to_path_buf(),
            location: location(),
            what,
            hint,
        };
        let mut found: Found = [None; 12];
        let decoder = &self.decoders[d];
        let decoded = match decoder {
            Decoder::Json => extract(payload, names, &mut found),
            Decoder::Protobuf(p) => p.extract(payload, &mut found),
            Decoder::Ros2(r) => r.extract(payload, &mut found),
        };
        decoded.map_err(|source| match decoder {
            Decoder::Json => IngestError::McapJsonMessage {
                path: path.to_path_buf(),
                location: location(),
                hint: format!(
                    "each message on {} must be a JSON object with the number field(s) {}",
                    plan.topic,
                    names
                        .iter()
                        .map(|n| format!("{n:?}"))
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
                source: Box::new(source),
            },
            other => IngestError::McapUndecodable {
                path: path.to_path_buf(),
                location: location(),
                sequence: header.sequence,
                decoder: other.name(),
                source: Box::new(source),
            },
        })?;
        for (k, (sig, field)) in plan.fields.iter().enumerate() {
            match found[k] {
                Some(x) if x.is_finite() => {}
                Some(x) => {
                    return Err(bad(
                        format!("field {field:?} is {x}, not a finite number"),
                        "NaN and inf are not measurements; drop such messages when logging".into(),
                    ))
                }
                None => {
                    return Err(bad(
                        format!("no number field {field:?} in {}", preview(payload)),
                        format!(
                            "set the field name of {} in [ingest.mcap] of the pipeline (field = \"...\")",
                            Signal::ALL[*sig]
                        ),
                    ))
                }
            }
        }
        let time_ns = if plan.header_time {
            match (found[STAMP_SLOTS.0], found[STAMP_SLOTS.1]) {
                (Some(s), Some(n)) if (0.0..1e10).contains(&s) && (0.0..1e9).contains(&n) => {
                    s as u64 * 1_000_000_000 + n as u64
                }
                (s, n) => {
                    return Err(bad(
                        format!(
                            "header stamp {} s {} ns is not a time (seconds ≥ 0, nanoseconds in [0, 1e9))",
                            s.unwrap_or(f64::NAN),
                            n.unwrap_or(f64::NAN)
                        ),
                        "the logger wrote no stamp into the header; use the log time (drop time = \"header\")".into(),
                    ))
                }
            }
        } else {
            header.log_time
        };
        let t_ref = *self.t_ref.get_or_insert(time_ns);
        self.times[t].push((time_ns as i128 - t_ref as i128) as f64 * 1e-9);
        for (k, (sig, _)) in self.topics[t].fields.iter().enumerate() {
            self.values[*sig].push(found[k].expect("checked above"));
        }
        Ok(())
    }

    /// Log time (ns) of a time in seconds after the reference.
    fn log_time(&self, t_s: f64) -> u64 {
        let t_ref = self.t_ref.unwrap_or(0);
        (t_ref as i128 + (t_s * 1e9).round() as i128).max(0) as u64
    }

    /// Every mapped topic must exist and have messages.
    fn check_topics(&self) -> Result<(), IngestError> {
        let topics = &self.topics;
        let missing: Vec<&TopicPlan> = topics.iter().filter(|p| !p.seen_channel).collect();
        if !missing.is_empty() {
            let mut listed: Vec<String> = self
                .present
                .iter()
                .map(|(t, n)| format!("{t} ({n} messages)"))
                .collect();
            for p in topics.iter().filter(|p| p.seen_channel) {
                listed.push(format!("{} ({} messages)", p.topic, p.messages));
            }
            listed.sort();
            return Err(IngestError::McapMissingTopics {
                path: self.path.to_path_buf(),
                missing: missing
                    .iter()
                    .map(|p| {
                        let sigs: Vec<&str> = p
                            .fields
                            .iter()
                            .map(|(s, _)| Signal::ALL[*s].key())
                            .collect();
                        format!("{} ({})", p.topic, sigs.join(", "))
                    })
                    .collect::<Vec<_>>()
                    .join(", "),
                present: if listed.is_empty() {
                    "no messages".into()
                } else {
                    listed.join(", ")
                },
            });
        }
        if let Some(p) = topics.iter().find(|p| p.messages == 0) {
            return Err(IngestError::McapNoMessages {
                path: self.path.to_path_buf(),
                topic: p.topic.clone(),
                signal: Signal::ALL[p.fields[0].0],
            });
        }
        Ok(())
    }

    /// Orders each topic by log time (MCAP does not promise order; equal times are errors);
    /// returns the permutation per topic (None when already in order).
    fn order_by_time(&mut self) -> Result<Vec<Option<Vec<usize>>>, IngestError> {
        let mut orders: Vec<Option<Vec<usize>>> = Vec::with_capacity(self.topics.len());
        for t in 0..self.times.len() {
            let ts = &self.times[t];
            if ts.windows(2).all(|w| w[0] < w[1]) {
                orders.push(None);
                continue;
            }
            let mut order: Vec<usize> = (0..ts.len()).collect();
            order.sort_by(|&a, &b| ts[a].total_cmp(&ts[b]).then(a.cmp(&b)));
            for w in order.windows(2) {
                if ts[w[0]] == ts[w[1]] {
                    return Err(IngestError::TimeNotIncreasing {
                        path: self.path.to_path_buf(),
                        location: Location::Mcap {
                            topic: self.topics[t].topic.clone(),
                            message: w[1],
                            log_time_ns: self.log_time(ts[w[1]]),
                        },
                        channel: format!("topic {}", self.topics[t].topic),
                        t_prev_s: ts[w[0]],
                        t_s: ts[w[1]],
                    });
                }
            }
            self.times[t] = order.iter().map(|&i| ts[i]).collect();
            orders.push(Some(order));
        }
        Ok(orders)
    }

    /// The run metadata and the channels in canonical units, each topic's samples in `orders`.
    fn finish(
        mut self,
        cfg: &IngestConfig,
        orders: &[Option<Vec<usize>>],
    ) -> Result<McapRead, IngestError> {
        let mut warnings = Vec::new();
        let metadata = match self.run_metadata.take() {
            Some(pairs) => {
                let name = format!("metadata record \"{MCAP_METADATA_NAME}\"");
                super::metadata_from_pairs(self.path, &name, &pairs)?
            }
            None => {
                warnings.push(Warning {
                    kind: WarningKind::NoMetadata,
                    message: format!(
                        "no metadata: the file has no \"{MCAP_METADATA_NAME}\" metadata record (ambient temperature, initial speed, condition unknown)"
                    ),
                });
                RunMetadata::default()
            }
        };
        let t_ref = self.t_ref.unwrap_or(0);
        let shared_times: Vec<Arc<Vec<f64>>> = std::mem::take(&mut self.times)
            .into_iter()
            .map(Arc::new)
            .collect();
        let mut channels = Vec::with_capacity(9);
        for s in Signal::ALL {
            let m = cfg.mcap_field(s);
            let t = self.topic_index[&m.topic];
            let factor = m.unit.to_canonical_factor();
            let raw = std::mem::take(&mut self.values[s.index()]);
            let v: Vec<f64> = match &orders[t] {
                None => raw.into_iter().map(|x| x * factor).collect(),
                Some(order) => order.iter().map(|&i| raw[i] * factor).collect(),
            };
            channels.push(RawChannel {
                signal: s,
                source: format!("{} .{} [{}]", m.topic, m.field, m.unit),
                time_s: Arc::clone(&shared_times[t]),
                values: v,
                locate: Locator::Mcap {
                    topic: m.topic.clone(),
                    t_ref_ns: t_ref,
                },
                dropped: 0,
            });
        }
        Ok(McapRead {
            channels,
            metadata,
            t0_ns: t_ref,
            warnings,
        })
    }
}

fn preview(data: &[u8]) -> String {
    let s = String::from_utf8_lossy(&data[..data.len().min(80)]);
    format!("{s:?}")
}

/// Extracts the named number fields of a JSON object without allocating; other fields are
/// skipped. `found[k]` receives field `names[k]` (at most 8 fields per topic).
fn extract<S: AsRef<str>>(data: &[u8], names: &[S], found: &mut Found) -> Result<(), DecodeError> {
    if names.len() > STAMP_SLOTS.0 {
        return Err(DecodeError::JsonTooManyFields { max: STAMP_SLOTS.0 });
    }
    let mut de = serde_json::Deserializer::from_slice(data);
    FieldsSeed { names, found }
        .deserialize(&mut de)
        .and_then(|_| de.end())
        .map_err(|source| DecodeError::JsonNotNumbers {
            preview: preview(data),
            source,
        })
}

struct FieldsSeed<'a, 'b, S> {
    names: &'a [S],
    found: &'b mut Found,
}

impl<'de, S: AsRef<str>> DeserializeSeed<'de> for FieldsSeed<'_, '_, S> {
    type Value = ();
    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        d.deserialize_map(self)
    }
}

impl<'de, S: AsRef<str>> Visitor<'de> for FieldsSeed<'_, '_, S> {
    type Value = ();
    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("a JSON object")
    }
    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<(), A::Error> {
        while let Some(key) = map.next_key::<KeyRef<'de>>()? {
            match self.names.iter().position(|n| n.as_ref() == key.as_str()) {
                Some(k) => {
                    let v: NumberOrNot = map.next_value()?;
                    match v {
                        NumberOrNot::Number(x) => self.found[k] = Some(x),
                        NumberOrNot::Other(kind) => {
                            return Err(serde::de::Error::custom(format!(
                                "field {:?} is {kind}, expected a number",
                                key.as_str()
                            )))
                        }
                    }
                }
                None => {
                    map.next_value::<IgnoredAny>()?;
                }
            }
        }
        Ok(())
    }
}

/// A JSON object key, borrowed when possible.
enum KeyRef<'de> {
    Borrowed(&'de str),
    Owned(String),
}

impl KeyRef<'_> {
    fn as_str(&self) -> &str {
        match self {
            KeyRef::Borrowed(s) => s,
            KeyRef::Owned(s) => s,
        }
    }
}

impl<'de> serde::Deserialize<'de> for KeyRef<'de> {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = KeyRef<'de>;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a string key")
            }
            fn visit_borrowed_str<E>(self, v: &'de str) -> Result<Self::Value, E> {
                Ok(KeyRef::Borrowed(v))
            }
            fn visit_str<E>(self, v: &str) -> Result<Self::Value, E> {
                Ok(KeyRef::Owned(v.to_string()))
            }
        }
        d.deserialize_str(V)
    }
}

/// A JSON value that is a number, or a description of what else it is.
enum NumberOrNot {
    Number(f64),
    Other(&'static str),
}

impl<'de> serde::Deserialize<'de> for NumberOrNot {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = NumberOrNot;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a JSON value")
            }
            fn visit_f64<E>(self, v: f64) -> Result<Self::Value, E> {
                Ok(NumberOrNot::Number(v))
            }
            fn visit_i64<E>(self, v: i64) -> Result<Self::Value, E> {
                Ok(NumberOrNot::Number(v as f64))
            }
            fn visit_u64<E>(self, v: u64) -> Result<Self::Value, E> {
                Ok(NumberOrNot::Number(v as f64))
            }
            fn visit_str<E>(self, _: &str) -> Result<Self::Value, E> {
                Ok(NumberOrNot::Other("a string"))
            }
            fn visit_bool<E>(self, _: bool) -> Result<Self::Value, E> {
                Ok(NumberOrNot::Other("a boolean"))
            }
            fn visit_unit<E>(self) -> Result<Self::Value, E> {
                Ok(NumberOrNot::Other("null"))
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(
                self,
                mut a: A,
            ) -> Result<Self::Value, A::Error> {
                while a.next_element::<IgnoredAny>()?.is_some() {}
                Ok(NumberOrNot::Other("an array"))
            }
            fn visit_map<A: MapAccess<'de>>(self, mut a: A) -> Result<Self::Value, A::Error> {
                while a.next_entry::<IgnoredAny, IgnoredAny>()?.is_some() {}
                Ok(NumberOrNot::Other("an object"))
            }
        }
        d.deserialize_any(V)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn extracts_named_numbers_and_skips_the_rest() {
        let mut found = [None; 12];
        extract(
            br#"{"stamp":{"sec":1,"nsec":2},"v":12.5,"note":"x","omega":[1,2]}"#,
            &["v"],
            &mut found,
        )
        .unwrap();
        assert_eq!(found[0], Some(12.5));
        let mut found = [None; 12];
        extract(br#"{"a":1,"b":-2e3}"#, &["b", "a", "c"], &mut found).unwrap();
        assert_eq!(&found[..3], &[Some(-2000.0), Some(1.0), None]);
    }

    #[test]
    fn non_numbers_and_bad_json_are_errors() {
        let mut found = [None; 12];
        let e = extract(br#"{"v":"12.5"}"#, &["v"], &mut found)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("field \"v\" is a string, expected a number"),
            "{e}"
        );
        let e = extract(br#"{"v":1.0"#, &["v"], &mut found)
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("not a JSON object of numbers"), "{e}");
        let e = extract(b"[1,2]", &["v"], &mut found)
            .unwrap_err()
            .to_string();
        assert!(e.contains("not a JSON object"), "{e}");
    }
}
