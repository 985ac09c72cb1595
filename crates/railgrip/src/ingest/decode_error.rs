//! Why a message decoder could not be built or a payload could not be read: field paths, the
//! JSON, protobuf and CDR decoders. The reader wraps these into [`super::IngestError`]s that
//! add the file, topic, message and a hint; the text here is the "what" part of those
//! messages, and an underlying library error stays reachable as the source.

use prost_reflect::prost;

/// A field path, schema or payload the decoders refuse. Byte offsets are counted from the
/// start of the payload (for CDR: including its 4-byte encapsulation header).
#[derive(Debug, thiserror::Error)]
pub enum DecodeError {
    // --- Field paths (`a.b[2].c`) ---
    #[error("field path {path:?}: {part:?} has an unclosed '['")]
    PathUnclosedIndex { path: String, part: String },
    #[error("field path {path:?}: index [{index}] is not a whole number")]
    PathIndexNotANumber { path: String, index: String },
    #[error("field path {path:?} has an empty name")]
    PathEmptyName { path: String },

    // --- Decoder construction ---
    /// More field paths than a message has value slots (`max`).
    #[error("more than {max} fields")]
    TooManyFields { max: usize },
    #[error("unknown encoding {encoding:?}; railgrip reads {supported}")]
    UnknownEncoding {
        encoding: String,
        supported: &'static str,
    },

    // --- JSON ---
    /// More JSON fields mapped to one topic than a message has value slots (`max`).
    #[error("more than {max} fields mapped to one topic")]
    JsonTooManyFields { max: usize },
    /// A payload that is not a JSON object whose mapped fields are numbers; `preview` is the
    /// start of the payload, quoted.
    #[error("not a JSON object of numbers: {source} in {preview}")]
    JsonNotNumbers {
        preview: String,
        #[source]
        source: serde_json::Error,
    },
    /// A payload that is not JSON at all (the whole-message decode).
    #[error("{source}")]
    Json {
        #[source]
        source: serde_json::Error,
    },

    // --- Resolving a field path against a schema (protobuf and ros2msg) ---
    #[error("{message} has no field {field:?}; its fields: {fields}")]
    NoSuchField {
        message: String,
        field: String,
        /// The message's fields, `type name` each, comma separated.
        fields: String,
    },
    #[error("{message}.{field} is a map (unsupported field type for a signal)")]
    MapField { message: String, field: String },
    /// An `[index]` on a protobuf field that is not repeated.
    #[error("{message}.{field} is not repeated; drop the [index]")]
    NotRepeated { message: String, field: String },
    /// A repeated protobuf field named without an `[index]`.
    #[error("{message}.{field} is a repeated field; pick an element, e.g. {field}[0]")]
    RepeatedWithoutIndex { message: String, field: String },
    /// An `[index]` on a ros2msg field that is not an array.
    #[error("{message}.{field} is not an array; drop the [index]")]
    NotArray { message: String, field: String },
    /// A ros2msg array named without an `[index]`.
    #[error("{message}.{field} is an array ({type_name}); pick an element, e.g. {field}[0]")]
    ArrayWithoutIndex {
        message: String,
        field: String,
        type_name: String,
    },
    /// An index past the end of a ros2msg fixed-size array of `len` elements.
    #[error("{message}.{field} has {len} elements; [{index}] is out of range")]
    FixedArrayIndex {
        message: String,
        field: String,
        len: usize,
        index: usize,
    },
    /// A path that goes on below a field that is not a message.
    #[error("{message}.{field} is a {type_name}, it has no fields")]
    NoSubfields {
        message: String,
        field: String,
        type_name: String,
    },
    /// A path that ends at a message; `field` names the field as the schema's decoder does
    /// (the path for protobuf, `Message.field` for ros2msg).
    #[error("{field} is a message ({message_type}); name a number field inside it, e.g. {path}.<field>; its fields: {fields}")]
    MessageNotNumber {
        field: String,
        message_type: String,
        path: String,
        fields: String,
    },
    /// A path that ends at a field of a type other than a number.
    #[error("{field} is a {type_name}, not a number (unsupported field type for a signal)")]
    NotANumber { field: String, type_name: String },

    // --- Protobuf schemas ---
    #[error("the protobuf schema {schema} is not a valid FileDescriptorSet: {source}")]
    ProtobufSchema {
        schema: String,
        #[source]
        source: prost_reflect::DescriptorError,
    },
    /// A FileDescriptorSet so malformed that prost-reflect panicked while describing what is
    /// wrong with it (an index into its empty file list); the panic is caught.
    #[error("the protobuf schema {schema} is not a valid FileDescriptorSet (its descriptor references a file the set does not hold)")]
    ProtobufSchemaBroken { schema: String },
    /// The FileDescriptorSet lacks the channel's message; `available` lists (some of) its
    /// messages.
    #[error("the schema's FileDescriptorSet has no message {schema}; it has {}", .available.join(", "))]
    ProtobufNoMessage {
        schema: String,
        available: Vec<String>,
    },
    #[error("time = \"header\" needs a google.protobuf.Timestamp at header.stamp or timestamp in {message}; its fields: {fields}")]
    ProtobufNoTimestamp { message: String, fields: String },

    // --- Protobuf payloads ---
    #[error("repeated field {field} has {count} element(s); [{index}] is out of range")]
    RepeatedIndex {
        field: String,
        count: usize,
        index: usize,
    },
    #[error("varint cut off at byte {offset}")]
    VarintCutOff { offset: usize },
    #[error("varint longer than 10 bytes at byte {offset}")]
    VarintTooLong { offset: usize },
    #[error("{needed} byte(s) needed at byte {offset}, but the message ends at byte {end} (truncated, or a length is corrupt)")]
    ProtobufTruncated {
        needed: usize,
        offset: usize,
        end: usize,
    },
    #[error("group (wire type {wire_type}) at byte {offset}: proto2 groups are not supported")]
    Group { wire_type: u8, offset: usize },
    #[error("invalid wire type {wire_type} at byte {offset}")]
    InvalidWireType { wire_type: u8, offset: usize },
    #[error("field number 0 at byte {offset}")]
    FieldNumberZero { offset: usize },
    /// A scalar field sent with another wire type than its schema type's.
    #[error("field {field} (number {number}) has wire type {found} at byte {offset}, its schema type needs {expected}")]
    WireTypeMismatch {
        field: String,
        number: u32,
        found: u8,
        expected: u8,
        offset: usize,
    },
    /// A message field sent with another wire type than 2 (length-delimited).
    #[error(
        "field {field} (number {number}) is a message but has wire type {found} at byte {offset}"
    )]
    MessageWireType {
        field: String,
        number: u32,
        found: u8,
        offset: usize,
    },
    /// prost-reflect's full decode refused the payload.
    #[error("{source}")]
    Protobuf {
        #[source]
        source: prost::DecodeError,
    },

    // --- ros2msg schemas ---
    #[error("the ros2msg schema {schema} is not UTF-8 text: {source}")]
    Ros2SchemaNotUtf8 {
        schema: String,
        #[source]
        source: std::str::Utf8Error,
    },
    #[error("a separator line is followed by {found:?}, expected \"MSG: pkg/Type\"")]
    Ros2SectionHeader { found: String },
    #[error("{message}: type {type_name:?} has an unclosed '['")]
    Ros2UnclosedArray { message: String, type_name: String },
    #[error("{message}: array size {size:?} of type {type_name:?} is not a number")]
    Ros2ArraySize {
        message: String,
        size: String,
        type_name: String,
    },
    #[error("{message}: fixed array {type_name:?} is larger than 2^20 elements")]
    Ros2ArrayTooLarge { message: String, type_name: String },
    /// Line `line` (1-based, within the message's definition) has a type only.
    #[error("{message}, line {line}: {text:?} has a type but no field name")]
    Ros2NoFieldName {
        message: String,
        line: usize,
        text: String,
    },
    /// A field whose message type `missing` has no `MSG:` section in the schema.
    #[error("{message}: field {field} has type {type_name}, but the schema has no definition of {missing} (MSG: {missing} section)")]
    Ros2NoDefinition {
        message: String,
        field: String,
        type_name: String,
        missing: String,
    },
    #[error("message {message} contains itself")]
    Ros2Recursive { message: String },
    #[error("messages are nested deeper than {max} levels (at {message})")]
    Ros2TooDeep { max: usize, message: String },
    #[error("message {message} serialises to no bytes (only zero-length arrays)")]
    Ros2Empty { message: String },
    /// `time = "header"` on a message whose `header.stamp` cannot be read.
    #[error("time = \"header\" needs a std_msgs/Header field `header`: {source}")]
    Ros2NoHeader {
        #[source]
        source: Box<DecodeError>,
    },

    // --- CDR payloads ---
    #[error("the CDR message is {len} bytes, shorter than its 4-byte encapsulation header")]
    CdrTooShort { len: usize },
    /// An encapsulation other than plain CDR; `name` is what the two bytes denote.
    #[error("CDR encapsulation {:02x} {:02x} ({name}) is not supported; railgrip reads plain CDR (00 00 big endian, 00 01 little endian)", .kind[0], .kind[1])]
    CdrEncapsulation { kind: [u8; 2], name: &'static str },
    #[error("not plain CDR")]
    NotPlainCdr,
    /// An index past the end of a sequence of `count` elements.
    #[error("{message}.{field} has {count} element(s); [{index}] is out of range")]
    SequenceIndex {
        message: String,
        field: String,
        count: usize,
        index: usize,
    },
    #[error("field {field} is a {type_name} (unsupported field type: its CDR width differs between DDS vendors)")]
    WString { field: String, type_name: String },
    /// A sequence count larger than the bytes left could hold.
    #[error("field {field} has {count} element(s), more than the {left} byte(s) left at byte {offset} can hold (a count is corrupt, or the message is cut short)")]
    CdrCount {
        field: String,
        count: usize,
        left: usize,
        offset: usize,
    },
    #[error("field {field} needs {needed} byte(s) at byte {offset}, but the message ends at byte {end} (truncated, or a length or count is corrupt)")]
    CdrTruncated {
        field: String,
        needed: usize,
        offset: usize,
        end: usize,
    },
}

#[cfg(test)]
mod tests {
    use std::error::Error;

    use super::*;
    use crate::format::MCAP_MESSAGE_ENCODING;
    use crate::ingest::MessageDecoder;

    #[test]
    fn library_errors_stay_reachable_as_the_source() {
        let e = MessageDecoder::new("protobuf", "a.B", b"\xff\xff", &[], false)
            .err()
            .unwrap();
        assert!(
            e.to_string()
                .starts_with("the protobuf schema a.B is not a valid FileDescriptorSet: "),
            "{e}"
        );
        assert!(e
            .source()
            .is_some_and(|s| s.is::<prost_reflect::DescriptorError>()));
        let json = MessageDecoder::new(MCAP_MESSAGE_ENCODING, "", b"", &[], false).unwrap();
        let e = json.decode_whole(b"{").unwrap_err();
        assert!(e.source().is_some_and(|s| s.is::<serde_json::Error>()));
        let e = json.extract(b"[1]", &["v"]).unwrap_err();
        assert!(matches!(e, DecodeError::JsonNotNumbers { .. }), "{e:?}");
        assert!(e.source().is_some_and(|s| s.is::<serde_json::Error>()));
        let e = MessageDecoder::new("cdr", "a/B", b"\xff", &[], false)
            .err()
            .unwrap();
        assert!(e.source().is_some_and(|s| s.is::<std::str::Utf8Error>()));
    }

    #[test]
    fn fields_are_structured_and_the_text_is_unchanged() {
        let e = MessageDecoder::new("cdr", "a/B", b"float64 x\n", &["x"], false)
            .unwrap()
            .extract(&[0, 7, 0, 0], &[])
            .unwrap_err();
        assert!(matches!(
            e,
            DecodeError::CdrEncapsulation {
                kind: [0, 7],
                name: "XCDR2"
            }
        ));
        assert_eq!(
            e.to_string(),
            "CDR encapsulation 00 07 (XCDR2) is not supported; railgrip reads plain CDR (00 00 big endian, 00 01 little endian)"
        );
        let e = MessageDecoder::new("cdr", "a/B", b"float64 x\n", &["x.y"], true)
            .err()
            .unwrap();
        assert_eq!(e.to_string(), "a/B.x is a float64, it has no fields");
        let e = crate::ingest::FieldPath::parse("a[x]").unwrap_err();
        assert_eq!(
            e.to_string(),
            "field path \"a[x]\": index [x] is not a whole number"
        );
    }
}
