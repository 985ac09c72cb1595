//! Protobuf messages in MCAP: the schema's FileDescriptorSet is read with prost-reflect, the
//! mapped field paths are resolved against the channel's message descriptor once, and each
//! payload is walked on the wire format, descending only into the messages on those paths
//! (no allocation per message). Semantics follow the protobuf encoding guide
//! (<https://protobuf.dev/programming-guides/encoding/>): the last occurrence of a scalar wins,
//! a nested message that occurs twice is merged, repeated scalars may be packed or not, an
//! absent field reads as its default (0 in proto3). `tests/mcap_encodings.rs` checks the walk
//! against prost-reflect's full `DynamicMessage` decode on random messages.
//!
//! Well-known wrappers (`google.protobuf.DoubleValue`, `FloatValue`, `Int64Value`, …) may be
//! named directly: `speed` reads `speed.value`. `time = "header"` reads a
//! `google.protobuf.Timestamp` at `header.stamp` or, as Foxglove's schemas have it, `timestamp`.

use prost_reflect::{Cardinality, DescriptorPool, FieldDescriptor, Kind, MessageDescriptor, Value};

use super::mcap::{FieldPath, Found, STAMP_SLOTS};
use super::DecodeError;

/// How a wanted field's value is decoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Scalar {
    Double,
    Float,
    Int32,
    Int64,
    Uint32,
    Uint64,
    Sint32,
    Sint64,
    Fixed32,
    Fixed64,
    Sfixed32,
    Sfixed64,
    Bool,
    Enum,
}

impl Scalar {
    fn of(kind: &Kind) -> Option<Scalar> {
        Some(match kind {
            Kind::Double => Scalar::Double,
            Kind::Float => Scalar::Float,
            Kind::Int32 => Scalar::Int32,
            Kind::Int64 => Scalar::Int64,
            Kind::Uint32 => Scalar::Uint32,
            Kind::Uint64 => Scalar::Uint64,
            Kind::Sint32 => Scalar::Sint32,
            Kind::Sint64 => Scalar::Sint64,
            Kind::Fixed32 => Scalar::Fixed32,
            Kind::Fixed64 => Scalar::Fixed64,
            Kind::Sfixed32 => Scalar::Sfixed32,
            Kind::Sfixed64 => Scalar::Sfixed64,
            Kind::Bool => Scalar::Bool,
            Kind::Enum(_) => Scalar::Enum,
            _ => return None,
        })
    }
    /// The wire type of one unpacked value.
    fn wire(self) -> u8 {
        match self {
            Scalar::Double | Scalar::Fixed64 | Scalar::Sfixed64 => 1,
            Scalar::Float | Scalar::Fixed32 | Scalar::Sfixed32 => 5,
            _ => 0,
        }
    }
}

#[derive(Debug, Clone)]
enum Take {
    /// The value into slot `.0`, decoded as `.1`.
    Value(usize, Scalar),
    Into(Node),
}

#[derive(Debug, Clone)]
struct Want {
    number: u32,
    name: String,
    repeated: bool,
    /// Element of a repeated field.
    index: Option<usize>,
    take: Take,
    /// Position of this want's element counter in the walk state.
    counter: usize,
}

#[derive(Debug, Clone, Default)]
struct Node {
    wants: Vec<Want>,
}

/// A protobuf message type and the fields one topic reads from it.
#[derive(Debug)]
pub(super) struct Decoder {
    message: MessageDescriptor,
    plan: Node,
    counters: usize,
    /// (slot, default) of every value, to fill in what a message leaves out.
    defaults: Vec<(usize, f64)>,
}

const WRAPPERS: [&str; 7] = [
    "google.protobuf.DoubleValue",
    "google.protobuf.FloatValue",
    "google.protobuf.Int64Value",
    "google.protobuf.UInt64Value",
    "google.protobuf.Int32Value",
    "google.protobuf.UInt32Value",
    "google.protobuf.BoolValue",
];

fn listing(m: &MessageDescriptor) -> String {
    m.fields()
        .map(|f| format!("{} {}", kind_name(&f), f.name()))
        .collect::<Vec<_>>()
        .join(", ")
}

fn kind_name(f: &FieldDescriptor) -> String {
    let k = match f.kind() {
        Kind::Message(m) => m.full_name().to_string(),
        Kind::Enum(e) => e.full_name().to_string(),
        k => format!("{k:?}").to_lowercase(),
    };
    if f.is_map() {
        "map".into()
    } else if f.is_list() {
        format!("repeated {k}")
    } else {
        k
    }
}

fn default_of(f: &FieldDescriptor) -> f64 {
    match f.default_value() {
        Value::F64(x) => x,
        Value::F32(x) => x as f64,
        Value::I32(x) | Value::EnumNumber(x) => x as f64,
        Value::I64(x) => x as f64,
        Value::U32(x) => x as f64,
        Value::U64(x) => x as f64,
        Value::Bool(b) => b as u8 as f64,
        _ => 0.0,
    }
}

impl Decoder {
    /// Compiles message `schema_name` of FileDescriptorSet `data` for the field paths
    /// `fields` (slots 0..) and, with `header_time`, the stamp into the stamp slots.
    pub(super) fn new(
        schema_name: &str,
        data: &[u8],
        fields: &[FieldPath],
        header_time: bool,
    ) -> Result<Decoder, DecodeError> {
        // prost-reflect 0.16 can panic while building the error of a corrupted set (its error
        // label indexes the set's files unchecked): a bad schema is an error, never a panic.
        let decoded = std::panic::catch_unwind(|| DescriptorPool::decode(data)).map_err(|_| {
            DecodeError::ProtobufSchemaBroken {
                schema: schema_name.to_string(),
            }
        })?;
        let pool = decoded.map_err(|source| DecodeError::ProtobufSchema {
            schema: schema_name.to_string(),
            source,
        })?;
        let message = pool.get_message_by_name(schema_name).ok_or_else(|| {
            DecodeError::ProtobufNoMessage {
                schema: schema_name.to_string(),
                available: pool
                    .all_messages()
                    .take(20)
                    .map(|m| m.full_name().to_string())
                    .collect(),
            }
        })?;
        let mut d = Decoder {
            message,
            plan: Node::default(),
            counters: 0,
            defaults: vec![],
        };
        for (slot, p) in fields.iter().enumerate() {
            d.add(p, slot)?;
        }
        if header_time {
            let stamp = ["header.stamp", "timestamp"]
                .into_iter()
                .find(|p| {
                    d.resolve(&FieldPath::parse(p).expect("valid"))
                        .ok()
                        .and_then(|chain| chain.last().cloned())
                        .is_some_and(|f| matches!(f.kind(), Kind::Message(m) if m.full_name() == "google.protobuf.Timestamp"))
                })
                .ok_or_else(|| DecodeError::ProtobufNoTimestamp {
                    message: d.message.full_name().to_string(),
                    fields: listing(&d.message),
                })?;
            d.add(
                &FieldPath::parse(&format!("{stamp}.seconds")).expect("valid"),
                STAMP_SLOTS.0,
            )?;
            d.add(
                &FieldPath::parse(&format!("{stamp}.nanos")).expect("valid"),
                STAMP_SLOTS.1,
            )?;
        }
        Ok(d)
    }

    /// The field descriptors along `path` (wrappers not unwrapped).
    fn resolve(&self, path: &FieldPath) -> Result<Vec<FieldDescriptor>, DecodeError> {
        let mut m = self.message.clone();
        let mut chain = Vec::new();
        for (depth, (name, index)) in path.segments.iter().enumerate() {
            let Some(f) = m.get_field_by_name(name) else {
                return Err(DecodeError::NoSuchField {
                    message: m.full_name().to_string(),
                    field: name.clone(),
                    fields: listing(&m),
                });
            };
            if f.is_map() {
                return Err(DecodeError::MapField {
                    message: m.full_name().to_string(),
                    field: name.clone(),
                });
            }
            match (f.is_list(), index) {
                (false, Some(_)) => {
                    return Err(DecodeError::NotRepeated {
                        message: m.full_name().to_string(),
                        field: name.clone(),
                    })
                }
                (true, None) => {
                    return Err(DecodeError::RepeatedWithoutIndex {
                        message: m.full_name().to_string(),
                        field: name.clone(),
                    })
                }
                _ => {}
            }
            let last = depth + 1 == path.segments.len();
            if !last {
                match f.kind() {
                    Kind::Message(sub) => m = sub,
                    _ => {
                        return Err(DecodeError::NoSubfields {
                            message: m.full_name().to_string(),
                            field: name.clone(),
                            type_name: kind_name(&f),
                        })
                    }
                }
            }
            chain.push(f);
        }
        Ok(chain)
    }

    fn add(&mut self, path: &FieldPath, slot: usize) -> Result<(), DecodeError> {
        let mut chain = self.resolve(path)?;
        let mut indexes: Vec<Option<usize>> = path.segments.iter().map(|s| s.1).collect();
        let last = chain.last().expect("paths have a segment").clone();
        let scalar = match last.kind() {
            // A well-known wrapper, read through its number `value` (a schema that only
            // borrows the name, without one such number field, is a message like any other).
            Kind::Message(m)
                if WRAPPERS.contains(&m.full_name())
                    && m.get_field_by_name("value")
                        .is_some_and(|v| !v.is_list() && Scalar::of(&v.kind()).is_some()) =>
            {
                let value = m.get_field_by_name("value").expect("checked above");
                let scalar = Scalar::of(&value.kind()).expect("checked above");
                chain.push(value);
                indexes.push(None);
                scalar
            }
            Kind::Message(m) => {
                return Err(DecodeError::MessageNotNumber {
                    field: path.text.clone(),
                    message_type: m.full_name().to_string(),
                    path: path.text.clone(),
                    fields: listing(&m),
                })
            }
            k => Scalar::of(&k).ok_or_else(|| DecodeError::NotANumber {
                field: path.text.clone(),
                type_name: kind_name(&last),
            })?,
        };
        let default = default_of(chain.last().expect("chain"));
        let mut node = &mut self.plan;
        for (k, f) in chain.iter().enumerate() {
            let index = indexes[k];
            let repeated = f.cardinality() == Cardinality::Repeated;
            if k + 1 == chain.len() {
                node.wants.push(Want {
                    number: f.number(),
                    name: f.name().to_string(),
                    repeated,
                    index,
                    take: Take::Value(slot, scalar),
                    counter: self.counters,
                });
                self.counters += 1;
                break;
            }
            let pos = node.wants.iter().position(|w| {
                w.number == f.number() && w.index == index && matches!(w.take, Take::Into(_))
            });
            let pos = match pos {
                Some(p) => p,
                None => {
                    node.wants.push(Want {
                        number: f.number(),
                        name: f.name().to_string(),
                        repeated,
                        index,
                        take: Take::Into(Node::default()),
                        counter: self.counters,
                    });
                    self.counters += 1;
                    node.wants.len() - 1
                }
            };
            node = match &mut node.wants[pos].take {
                Take::Into(n) => n,
                Take::Value(..) => unreachable!(),
            };
        }
        self.defaults.push((slot, default));
        Ok(())
    }

    /// Reads the planned fields of one protobuf payload into `found`.
    pub(super) fn extract(&self, payload: &[u8], found: &mut Found) -> Result<(), DecodeError> {
        for &(slot, default) in &self.defaults {
            found[slot] = Some(default);
        }
        let mut counts = [0usize; 32];
        let mut heap;
        let counts: &mut [usize] = if self.counters <= counts.len() {
            &mut counts[..self.counters]
        } else {
            heap = vec![0usize; self.counters];
            &mut heap
        };
        walk(payload, 0, &self.plan, found, counts)?;
        // A repeated element that never came is an error, not a default.
        check_indexes(&self.plan, counts)
    }

    /// prost-reflect's full decode of a payload (the bare decode the benchmark compares with).
    pub fn decode_dynamic(
        &self,
        payload: &[u8],
    ) -> Result<prost_reflect::DynamicMessage, DecodeError> {
        prost_reflect::DynamicMessage::decode(self.message.clone(), payload)
            .map_err(|source| DecodeError::Protobuf { source })
    }
}

fn check_indexes(node: &Node, counts: &[usize]) -> Result<(), DecodeError> {
    for w in &node.wants {
        if let Some(i) = w.index {
            if counts[w.counter] <= i {
                return Err(DecodeError::RepeatedIndex {
                    field: w.name.clone(),
                    count: counts[w.counter],
                    index: i,
                });
            }
        }
        if let Take::Into(sub) = &w.take {
            check_indexes(sub, counts)?;
        }
    }
    Ok(())
}

struct Wire<'a> {
    buf: &'a [u8],
    pos: usize,
    /// Offset of `buf` in the whole payload, for messages.
    base: usize,
}

impl Wire<'_> {
    fn at(&self) -> usize {
        self.base + self.pos
    }
    fn varint(&mut self) -> Result<u64, DecodeError> {
        let mut x = 0u64;
        for k in 0..10 {
            let Some(&b) = self.buf.get(self.pos) else {
                return Err(DecodeError::VarintCutOff { offset: self.at() });
            };
            self.pos += 1;
            x |= ((b & 0x7f) as u64) << (7 * k);
            if b < 0x80 {
                return Ok(x);
            }
        }
        Err(DecodeError::VarintTooLong { offset: self.at() })
    }
    fn take(&mut self, n: usize) -> Result<&[u8], DecodeError> {
        let end = self
            .pos
            .checked_add(n)
            .filter(|&e| e <= self.buf.len())
            .ok_or_else(|| DecodeError::ProtobufTruncated {
                needed: n,
                offset: self.at(),
                end: self.base + self.buf.len(),
            })?;
        let s = &self.buf[self.pos..end];
        self.pos = end;
        Ok(s)
    }
    fn skip(&mut self, wire: u8) -> Result<(), DecodeError> {
        match wire {
            0 => self.varint().map(|_| ()),
            1 => self.take(8).map(|_| ()),
            5 => self.take(4).map(|_| ()),
            2 => {
                let n = self.varint()? as usize;
                self.take(n).map(|_| ())
            }
            3 | 4 => Err(DecodeError::Group {
                wire_type: wire,
                offset: self.at(),
            }),
            w => Err(DecodeError::InvalidWireType {
                wire_type: w,
                offset: self.at(),
            }),
        }
    }
    /// One value of `s`, sent with wire type `wire` (already known to match).
    fn scalar(&mut self, s: Scalar) -> Result<f64, DecodeError> {
        Ok(match s {
            Scalar::Double => f64::from_le_bytes(self.take(8)?.try_into().expect("8")),
            Scalar::Float => f32::from_le_bytes(self.take(4)?.try_into().expect("4")) as f64,
            Scalar::Fixed64 => u64::from_le_bytes(self.take(8)?.try_into().expect("8")) as f64,
            Scalar::Sfixed64 => i64::from_le_bytes(self.take(8)?.try_into().expect("8")) as f64,
            Scalar::Fixed32 => u32::from_le_bytes(self.take(4)?.try_into().expect("4")) as f64,
            Scalar::Sfixed32 => i32::from_le_bytes(self.take(4)?.try_into().expect("4")) as f64,
            Scalar::Int32 | Scalar::Enum => self.varint()? as i32 as f64,
            Scalar::Int64 => self.varint()? as i64 as f64,
            Scalar::Uint32 => self.varint()? as u32 as f64,
            Scalar::Uint64 => self.varint()? as f64,
            Scalar::Sint32 => {
                let v = self.varint()? as u32;
                ((v >> 1) as i32 ^ -((v & 1) as i32)) as f64
            }
            Scalar::Sint64 => {
                let v = self.varint()?;
                ((v >> 1) as i64 ^ -((v & 1) as i64)) as f64
            }
            Scalar::Bool => (self.varint()? != 0) as u8 as f64,
        })
    }
}

fn walk(
    buf: &[u8],
    base: usize,
    node: &Node,
    found: &mut Found,
    counts: &mut [usize],
) -> Result<(), DecodeError> {
    let mut w = Wire { buf, pos: 0, base };
    while w.pos < buf.len() {
        let tag_at = w.at();
        let tag = w.varint()?;
        let number = (tag >> 3) as u32;
        let wire = (tag & 7) as u8;
        if number == 0 {
            return Err(DecodeError::FieldNumberZero { offset: tag_at });
        }
        let mut matched = false;
        for want in node.wants.iter().filter(|x| x.number == number) {
            matched = true;
            let save = w.pos;
            match &want.take {
                Take::Value(slot, s) => {
                    if want.repeated && wire == 2 && s.wire() != 2 {
                        // Packed: a length, then the values back to back.
                        let n = w.varint()? as usize;
                        let start = w.at();
                        let body = w.take(n)?;
                        let mut p = Wire {
                            buf: body,
                            pos: 0,
                            base: start,
                        };
                        while p.pos < body.len() {
                            let x = p.scalar(*s)?;
                            if want.index == Some(counts[want.counter]) {
                                found[*slot] = Some(x);
                            }
                            counts[want.counter] += 1;
                        }
                    } else if wire == s.wire() {
                        let x = w.scalar(*s)?;
                        if !want.repeated || want.index == Some(counts[want.counter]) {
                            found[*slot] = Some(x);
                        }
                        counts[want.counter] += 1;
                    } else {
                        return Err(DecodeError::WireTypeMismatch {
                            field: want.name.clone(),
                            number,
                            found: wire,
                            expected: s.wire(),
                            offset: tag_at,
                        });
                    }
                }
                Take::Into(sub) => {
                    if wire != 2 {
                        return Err(DecodeError::MessageWireType {
                            field: want.name.clone(),
                            number,
                            found: wire,
                            offset: tag_at,
                        });
                    }
                    let n = w.varint()? as usize;
                    let start = w.at();
                    let body = w.take(n)?;
                    let mine = !want.repeated || want.index == Some(counts[want.counter]);
                    counts[want.counter] += 1;
                    if mine {
                        walk(body, start, sub, found, counts)?;
                    }
                }
            }
            // Several wants may read the same field (two elements of one list).
            if node.wants.iter().filter(|x| x.number == number).count() > 1 {
                w.pos = save;
            }
        }
        // Unwanted fields are skipped; a field several wants read was rewound after each.
        if !matched || node.wants.iter().filter(|x| x.number == number).count() > 1 {
            w.skip(wire)?;
        }
    }
    Ok(())
}
