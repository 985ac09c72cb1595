//! ROS 2 messages in MCAP: `ros2msg` schemas and CDR-encoded payloads, read without ROS.
//!
//! # Schema grammar (what MCAP stores for `ros2msg`)
//!
//! The schema data is the message definition of the channel's type followed by the definitions
//! it depends on, each after a separator line of `=` characters and a line `MSG: pkg/Type`:
//!
//! ```text
//! schema   := section ( "====…" NL "MSG: " type NL section )*
//! section  := ( comment | blank | constant | field )*
//! field    := type NAME [default]          # default values are ignored
//! constant := type NAME "=" value          # skipped (constants are not serialised)
//! type     := base [ "[" [ "<=" ] [N] "]" ]   # fixed array T[N], sequence T[] or T[<=N]
//! base     := bool | byte | char | int8 … uint64 | float32 | float64
//!           | string [ "<=" N ] | wstring [ "<=" N ] | [ pkg "/" [ "msg/" ] ] Name
//! ```
//!
//! An unqualified `Name` is looked up in the package of the message that uses it (`Header`
//! alone means `std_msgs/Header`); `builtin_interfaces/Time` and `Duration` (and ROS 1
//! `time`/`duration`) are known without a definition (`int32 sec`, `uint32 nanosec`).
//!
//! # CDR (OMG CDR version 1, as ROS 2's rmw layers write it)
//!
//! Four bytes of encapsulation header (`00 00` big endian, `00 01` little endian, then two
//! option bytes), then the fields in order: primitives aligned to their size (relative to the
//! end of the header, 8 at most), `string` as a 4-aligned `uint32` length that counts the NUL
//! terminator then the bytes, sequences as a 4-aligned `uint32` count then the elements, fixed
//! arrays as the elements alone, nested messages inline. `wstring` (whose width differs between
//! DDS vendors) is refused. Other encapsulations (parameter lists, XCDR2) are refused by name.

use std::collections::HashMap;

use super::mcap::{FieldPath, Found, STAMP_SLOTS};
use super::DecodeError;

/// Primitive types and their CDR sizes (also their alignment).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Prim {
    Bool,
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    I64,
    U64,
    F32,
    F64,
}

impl Prim {
    fn from_name(s: &str) -> Option<Prim> {
        Some(match s {
            "bool" => Prim::Bool,
            "int8" => Prim::I8,
            "byte" | "char" | "uint8" => Prim::U8,
            "int16" => Prim::I16,
            "uint16" => Prim::U16,
            "int32" => Prim::I32,
            "uint32" => Prim::U32,
            "int64" => Prim::I64,
            "uint64" => Prim::U64,
            "float32" => Prim::F32,
            "float64" => Prim::F64,
            _ => return None,
        })
    }
    fn size(self) -> usize {
        match self {
            Prim::Bool | Prim::I8 | Prim::U8 => 1,
            Prim::I16 | Prim::U16 => 2,
            Prim::I32 | Prim::U32 | Prim::F32 => 4,
            Prim::I64 | Prim::U64 | Prim::F64 => 8,
        }
    }
}

#[derive(Debug, Clone, PartialEq)]
enum Ty {
    Prim(Prim),
    String,
    WString,
    Msg(usize),
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Arity {
    One,
    Fixed(usize),
    Sequence,
}

#[derive(Debug, Clone)]
struct Field {
    name: String,
    /// As written in the schema, for messages.
    type_text: String,
    ty: Ty,
    arity: Arity,
}

#[derive(Debug, Clone)]
struct MsgDef {
    name: String,
    fields: Vec<Field>,
}

/// What to take from a field: a value into slot `slot`, or a nested message's fields.
#[derive(Debug, Clone)]
enum Take {
    Value(usize),
    Into(Node),
}

/// The wanted fields of one message, by field index, each with an element index for arrays.
#[derive(Debug, Clone, Default)]
struct Node {
    wants: Vec<(usize, Option<usize>, Take)>,
}

/// A compiled `ros2msg` schema and the fields one topic reads from it.
#[derive(Debug)]
pub(super) struct Decoder {
    defs: Vec<MsgDef>,
    root: usize,
    plan: Node,
    /// Values to capture before the walk can stop.
    targets: usize,
}

fn normalise(name: &str) -> String {
    let parts: Vec<&str> = name.split('/').collect();
    match parts.as_slice() {
        [pkg, "msg", ty] => format!("{pkg}/{ty}"),
        _ => name.to_string(),
    }
}

fn package_of(name: &str) -> &str {
    name.split('/').next().unwrap_or("")
}

/// The sections of a schema: (type name, definition text); the first is the root type.
fn sections<'a>(root: &str, text: &'a str) -> Result<Vec<(String, Vec<&'a str>)>, DecodeError> {
    let mut out = vec![(normalise(root), Vec::new())];
    let mut lines = text.lines().peekable();
    while let Some(line) = lines.next() {
        let t = line.trim();
        if t.len() >= 3 && t.chars().all(|c| c == '=') {
            let header = lines.next().unwrap_or("").trim();
            let name =
                header
                    .strip_prefix("MSG:")
                    .ok_or_else(|| DecodeError::Ros2SectionHeader {
                        found: header.to_string(),
                    })?;
            out.push((normalise(name.trim()), Vec::new()));
        } else {
            out.last_mut().expect("root").1.push(line);
        }
    }
    Ok(out)
}

/// Parses a type such as `float64[3]`, `string<=10`, `geometry_msgs/Vector3[]`, `int8[<=4]`
/// of a field of message `message` (named in errors).
fn split_type<'t>(message: &str, t: &'t str) -> Result<(&'t str, Arity), DecodeError> {
    let Some(open) = t.find('[') else {
        return Ok((t, Arity::One));
    };
    let inner = t[open + 1..]
        .strip_suffix(']')
        .ok_or_else(|| DecodeError::Ros2UnclosedArray {
            message: message.to_string(),
            type_name: t.to_string(),
        })?;
    let base = &t[..open];
    if inner.is_empty() || inner.starts_with("<=") {
        return Ok((base, Arity::Sequence));
    }
    let n: usize = inner.parse().map_err(|_| DecodeError::Ros2ArraySize {
        message: message.to_string(),
        size: inner.to_string(),
        type_name: t.to_string(),
    })?;
    if n > 1 << 20 {
        return Err(DecodeError::Ros2ArrayTooLarge {
            message: message.to_string(),
            type_name: t.to_string(),
        });
    }
    Ok((base, Arity::Fixed(n)))
}

/// Parses a `ros2msg` schema whose root type is `root`.
fn parse_schema(root: &str, text: &str) -> Result<(Vec<MsgDef>, usize), DecodeError> {
    let secs = sections(root, text)?;
    let mut index: HashMap<String, usize> = HashMap::new();
    let mut defs: Vec<MsgDef> = Vec::new();
    for (name, _) in &secs {
        if index.contains_key(name) {
            continue;
        }
        index.insert(name.clone(), defs.len());
        defs.push(MsgDef {
            name: name.clone(),
            fields: vec![],
        });
    }
    // Time and Duration are known without a definition.
    for builtin in ["builtin_interfaces/Time", "builtin_interfaces/Duration"] {
        if !index.contains_key(builtin) {
            index.insert(builtin.to_string(), defs.len());
            defs.push(MsgDef {
                name: builtin.to_string(),
                fields: vec![
                    Field {
                        name: "sec".into(),
                        type_text: "int32".into(),
                        ty: Ty::Prim(Prim::I32),
                        arity: Arity::One,
                    },
                    Field {
                        name: "nanosec".into(),
                        type_text: "uint32".into(),
                        ty: Ty::Prim(Prim::U32),
                        arity: Arity::One,
                    },
                ],
            });
        }
    }
    let mut seen = std::collections::HashSet::new();
    for (name, lines) in &secs {
        if !seen.insert(name.clone()) {
            continue;
        }
        let pkg = package_of(name);
        let mut fields = Vec::new();
        for (k, raw) in lines.iter().enumerate() {
            let line = match raw.find('#') {
                Some(h) => &raw[..h],
                None => raw,
            }
            .trim();
            if line.is_empty() {
                continue;
            }
            let mut words = line.split_whitespace();
            let type_text = words.next().expect("not empty");
            let Some(field_name) = words.next() else {
                return Err(DecodeError::Ros2NoFieldName {
                    message: name.clone(),
                    line: k + 1,
                    text: line.to_string(),
                });
            };
            if field_name.contains('=') || words.clone().next().is_some_and(|w| w.starts_with('='))
            {
                continue; // a constant
            }
            let (base, arity) = split_type(name, type_text)?;
            let base = base.split("<=").next().unwrap_or(base);
            let ty = if let Some(p) = Prim::from_name(base) {
                Ty::Prim(p)
            } else if base == "string" {
                Ty::String
            } else if base == "wstring" {
                Ty::WString
            } else {
                let full = match base {
                    "Header" => "std_msgs/Header".to_string(),
                    "time" => "builtin_interfaces/Time".to_string(),
                    "duration" => "builtin_interfaces/Duration".to_string(),
                    b if b.contains('/') => normalise(b),
                    b => format!("{pkg}/{b}"),
                };
                match index.get(&full) {
                    Some(&i) => Ty::Msg(i),
                    None => {
                        return Err(DecodeError::Ros2NoDefinition {
                            message: name.clone(),
                            field: field_name.to_string(),
                            type_name: type_text.to_string(),
                            missing: full,
                        })
                    }
                }
            };
            fields.push(Field {
                name: field_name.to_string(),
                type_text: type_text.to_string(),
                ty,
                arity,
            });
        }
        defs[index[name]].fields = fields;
    }
    check_shape(&defs, 0)?;
    Ok((defs, 0))
}

/// Deepest nesting of messages accepted (the walks recurse once per level).
const MAX_DEPTH: usize = 64;

/// Refuses what would make the walks loop or recurse without bound: a message that contains
/// itself (CDR has no optional members to end it), nesting deeper than [`MAX_DEPTH`], and a
/// message that serialises to no bytes (a count of such elements would cost time but no input).
/// Each message is examined once (memoised), so a schema of shared sub-messages stays linear.
fn check_shape(defs: &[MsgDef], root: usize) -> Result<(), DecodeError> {
    #[derive(Clone, Copy, PartialEq)]
    enum State {
        New,
        Open,
        Done(usize),
    }
    fn visit(
        defs: &[MsgDef],
        m: usize,
        state: &mut [State],
        depth: usize,
    ) -> Result<usize, DecodeError> {
        match state[m] {
            State::Done(min) => return Ok(min),
            State::Open => {
                return Err(DecodeError::Ros2Recursive {
                    message: defs[m].name.clone(),
                })
            }
            State::New => {}
        }
        if depth > MAX_DEPTH {
            return Err(DecodeError::Ros2TooDeep {
                max: MAX_DEPTH,
                message: defs[m].name.clone(),
            });
        }
        state[m] = State::Open;
        // Fewest bytes a message can take (alignment padding aside).
        let mut min = 0usize;
        for f in &defs[m].fields {
            let one = match f.ty {
                Ty::Prim(p) => p.size(),
                Ty::String | Ty::WString => 4,
                Ty::Msg(i) => visit(defs, i, state, depth + 1)?,
            };
            min = min.saturating_add(match f.arity {
                Arity::One => one,
                Arity::Fixed(n) => one.saturating_mul(n),
                Arity::Sequence => 4,
            });
        }
        if defs[m].fields.is_empty() {
            min = 1; // the placeholder byte of an empty message
        }
        if min == 0 {
            return Err(DecodeError::Ros2Empty {
                message: defs[m].name.clone(),
            });
        }
        state[m] = State::Done(min);
        Ok(min)
    }
    let mut state = vec![State::New; defs.len()];
    visit(defs, root, &mut state, 0).map(|_| ())
}

impl Decoder {
    /// Compiles schema `schema_name` (`ros2msg` text `data`) for the field paths `fields`
    /// (captured into slots 0..) and, with `header_time`, `header.stamp` into the stamp slots.
    pub(super) fn new(
        schema_name: &str,
        data: &[u8],
        fields: &[FieldPath],
        header_time: bool,
    ) -> Result<Decoder, DecodeError> {
        let text = std::str::from_utf8(data).map_err(|source| DecodeError::Ros2SchemaNotUtf8 {
            schema: schema_name.to_string(),
            source,
        })?;
        let (defs, root) = parse_schema(schema_name, text)?;
        let mut d = Decoder {
            defs,
            root,
            plan: Node::default(),
            targets: 0,
        };
        for (slot, path) in fields.iter().enumerate() {
            d.add(path, slot)?;
        }
        if header_time {
            let stamp = FieldPath::parse("header.stamp.sec").expect("valid");
            let nanos = FieldPath::parse("header.stamp.nanosec").expect("valid");
            d.add(&stamp, STAMP_SLOTS.0)
                .map_err(|e| DecodeError::Ros2NoHeader {
                    source: Box::new(e),
                })?;
            d.add(&nanos, STAMP_SLOTS.1)?;
        }
        Ok(d)
    }

    /// The fields of message `m`, for error messages.
    fn listing(&self, m: usize) -> String {
        self.defs[m]
            .fields
            .iter()
            .map(|f| format!("{} {}", f.type_text, f.name))
            .collect::<Vec<_>>()
            .join(", ")
    }

    fn add(&mut self, path: &FieldPath, slot: usize) -> Result<(), DecodeError> {
        let mut m = self.root;
        let mut chain: Vec<(usize, Option<usize>)> = Vec::new();
        for (depth, (name, index)) in path.segments.iter().enumerate() {
            let def = &self.defs[m];
            let Some(fi) = def.fields.iter().position(|f| &f.name == name) else {
                return Err(DecodeError::NoSuchField {
                    message: def.name.clone(),
                    field: name.clone(),
                    fields: self.listing(m),
                });
            };
            let f = &def.fields[fi];
            match (f.arity, index) {
                (Arity::One, Some(_)) => {
                    return Err(DecodeError::NotArray {
                        message: def.name.clone(),
                        field: name.clone(),
                    })
                }
                (Arity::Fixed(_) | Arity::Sequence, None) => {
                    return Err(DecodeError::ArrayWithoutIndex {
                        message: def.name.clone(),
                        field: name.clone(),
                        type_name: f.type_text.clone(),
                    })
                }
                (Arity::Fixed(n), Some(i)) if *i >= n => {
                    return Err(DecodeError::FixedArrayIndex {
                        message: def.name.clone(),
                        field: name.clone(),
                        len: n,
                        index: *i,
                    })
                }
                _ => {}
            }
            let last = depth + 1 == path.segments.len();
            match (&f.ty, last) {
                (Ty::Msg(i), false) => m = *i,
                (Ty::Prim(_), true) => {}
                (Ty::Msg(i), true) => {
                    return Err(DecodeError::MessageNotNumber {
                        field: format!("{}.{name}", def.name),
                        message_type: f.type_text.clone(),
                        path: path.text.clone(),
                        fields: self.listing(*i),
                    })
                }
                (Ty::String | Ty::WString, true) => {
                    return Err(DecodeError::NotANumber {
                        field: format!("{}.{name}", def.name),
                        type_name: f.type_text.clone(),
                    })
                }
                (_, false) => {
                    return Err(DecodeError::NoSubfields {
                        message: def.name.clone(),
                        field: name.clone(),
                        type_name: f.type_text.clone(),
                    })
                }
            }
            chain.push((fi, *index));
        }
        // Insert into the plan tree.
        let mut node = &mut self.plan;
        for (k, (fi, index)) in chain.iter().enumerate() {
            let last = k + 1 == chain.len();
            if last {
                node.wants.push((*fi, *index, Take::Value(slot)));
                node.wants.sort_by_key(|w| w.0);
                break;
            }
            let pos = node
                .wants
                .iter()
                .position(|w| w.0 == *fi && w.1 == *index && matches!(w.2, Take::Into(_)));
            let pos = match pos {
                Some(p) => p,
                None => {
                    node.wants.push((*fi, *index, Take::Into(Node::default())));
                    node.wants.sort_by_key(|w| w.0);
                    node.wants
                        .iter()
                        .position(|w| w.0 == *fi && w.1 == *index && matches!(w.2, Take::Into(_)))
                        .expect("just pushed")
                }
            };
            node = match &mut node.wants[pos].2 {
                Take::Into(n) => n,
                Take::Value(_) => unreachable!(),
            };
        }
        self.targets += 1;
        Ok(())
    }

    /// Reads the planned fields of one CDR payload into `found`.
    pub(super) fn extract(&self, payload: &[u8], found: &mut Found) -> Result<(), DecodeError> {
        if payload.len() < 4 {
            return Err(DecodeError::CdrTooShort { len: payload.len() });
        }
        let le = match (payload[0], payload[1]) {
            (0, 0) => false,
            (0, 1) => true,
            (a, b) => {
                let name = match (a, b) {
                    (0, 2) | (0, 3) => "PL_CDR (parameter list)",
                    (0, 6..=11) | (0, 0x10..=0x15) => "XCDR2",
                    _ => "unknown",
                };
                return Err(DecodeError::CdrEncapsulation { kind: [a, b], name });
            }
        };
        let mut c = Cdr {
            buf: &payload[4..],
            pos: 0,
            le,
            left: self.targets,
        };
        match self.walk(&mut c, self.root, &self.plan, found) {
            Ok(()) | Err(Stop::Done) => Ok(()),
            Err(Stop::Bad(e)) => Err(e),
        }
    }

    fn walk(&self, c: &mut Cdr, m: usize, node: &Node, found: &mut Found) -> Result<(), Stop> {
        let def = &self.defs[m];
        if def.fields.is_empty() {
            // ROS 2 serialises an empty message as one placeholder byte.
            c.skip(1, 1, "empty message placeholder")?;
            return Ok(());
        }
        let mut w = 0;
        for (fi, f) in def.fields.iter().enumerate() {
            let start = w;
            while w < node.wants.len() && node.wants[w].0 == fi {
                w += 1;
            }
            let wants = &node.wants[start..w];
            let count = c.count(f)?;
            if wants.is_empty() {
                self.skip_elements(c, f, count)?;
                continue;
            }
            for k in 0..count {
                let n = wants.iter().filter(|w| w.1.is_none_or(|i| i == k)).count();
                if n == 0 {
                    self.skip_elements(c, f, 1)?;
                    continue;
                }
                let at = c.pos;
                for (_, _, take) in wants.iter().filter(|w| w.1.is_none_or(|i| i == k)) {
                    // With several paths into one element each starts from its beginning.
                    c.pos = at;
                    match (take, &f.ty) {
                        (Take::Value(slot), Ty::Prim(p)) => {
                            found[*slot] = Some(c.prim(*p, &f.name)?);
                            c.left -= 1;
                        }
                        (Take::Into(sub), Ty::Msg(i)) => self.walk(c, *i, sub, found)?,
                        _ => unreachable!("paths are checked against the schema"),
                    }
                    if c.left == 0 {
                        return Err(Stop::Done);
                    }
                }
                if n > 1 {
                    c.pos = at;
                    self.skip_elements(c, f, 1)?;
                }
            }
            if let Arity::Sequence = f.arity {
                if let Some((_, Some(i), _)) =
                    wants.iter().find(|w| w.1.is_some_and(|i| i >= count))
                {
                    return Err(Stop::Bad(DecodeError::SequenceIndex {
                        message: def.name.clone(),
                        field: f.name.clone(),
                        count,
                        index: *i,
                    }));
                }
            }
        }
        Ok(())
    }

    fn skip_elements(&self, c: &mut Cdr, f: &Field, count: usize) -> Result<(), Stop> {
        match &f.ty {
            Ty::Prim(p) => {
                if count > 0 {
                    c.skip(p.size(), p.size() * count, &f.name)?;
                }
            }
            Ty::String => {
                for _ in 0..count {
                    let n = c.u32(&f.name)? as usize;
                    c.skip(1, n, &f.name)?;
                }
            }
            Ty::WString => {
                return Err(Stop::Bad(DecodeError::WString {
                    field: f.name.clone(),
                    type_name: f.type_text.clone(),
                }))
            }
            Ty::Msg(i) => {
                for _ in 0..count {
                    let left = c.left;
                    c.left = usize::MAX;
                    self.walk(c, *i, &Node::default(), &mut [None; 12])?;
                    c.left = left;
                }
            }
        }
        Ok(())
    }

    /// Every field of a payload visited, primitives converted (the bare decode the benchmark
    /// compares with): returns the number of values read.
    pub fn decode_all(&self, payload: &[u8]) -> Result<usize, DecodeError> {
        if payload.len() < 4 || payload[0] != 0 || payload[1] > 1 {
            return Err(DecodeError::NotPlainCdr);
        }
        let mut c = Cdr {
            buf: &payload[4..],
            pos: 0,
            le: payload[1] == 1,
            left: usize::MAX,
        };
        let mut n = 0;
        match self.visit_all(&mut c, self.root, &mut n) {
            // `visit_all` plans no values, so it never stops early.
            Ok(()) | Err(Stop::Done) => Ok(n),
            Err(Stop::Bad(e)) => Err(e),
        }
    }

    fn visit_all(&self, c: &mut Cdr, m: usize, n: &mut usize) -> Result<(), Stop> {
        let def = &self.defs[m];
        if def.fields.is_empty() {
            return c.skip(1, 1, "placeholder");
        }
        for f in &def.fields {
            let count = c.count(f)?;
            match f.ty {
                Ty::Prim(p) => {
                    for _ in 0..count {
                        std::hint::black_box(c.prim(p, &f.name)?);
                        *n += 1;
                    }
                }
                Ty::Msg(i) => {
                    for _ in 0..count {
                        self.visit_all(c, i, n)?;
                    }
                }
                _ => self.skip_elements(c, f, count)?,
            }
        }
        Ok(())
    }
}

enum Stop {
    /// Every planned value was read: the rest of the message need not be walked.
    Done,
    Bad(DecodeError),
}

impl From<DecodeError> for Stop {
    fn from(e: DecodeError) -> Stop {
        Stop::Bad(e)
    }
}

struct Cdr<'a> {
    /// The payload after the 4-byte encapsulation header (alignment is relative to it).
    buf: &'a [u8],
    pos: usize,
    le: bool,
    /// Planned values not read yet.
    left: usize,
}

impl Cdr<'_> {
    /// Elements of field `f`: 1, its fixed size, or a sequence's count — which may not exceed
    /// the bytes left, since every element takes at least one (checked by `check_shape`).
    fn count(&mut self, f: &Field) -> Result<usize, Stop> {
        let n = match f.arity {
            Arity::One => return Ok(1),
            Arity::Fixed(n) => n,
            Arity::Sequence => self.u32(&f.name)? as usize,
        };
        let left = self.buf.len().saturating_sub(self.pos);
        if n > left {
            return Err(Stop::Bad(DecodeError::CdrCount {
                field: f.name.clone(),
                count: n,
                left,
                offset: self.pos + 4,
            }));
        }
        Ok(n)
    }

    /// Aligns to `align` and skips `n` bytes.
    fn skip(&mut self, align: usize, n: usize, what: &str) -> Result<(), Stop> {
        let at = (self.pos + align - 1) & !(align - 1);
        let end = at.checked_add(n).filter(|&e| e <= self.buf.len());
        match end {
            Some(e) => {
                self.pos = e;
                Ok(())
            }
            None => Err(Stop::Bad(DecodeError::CdrTruncated {
                field: what.to_string(),
                needed: n,
                offset: at + 4,
                end: self.buf.len() + 4,
            })),
        }
    }

    fn bytes<const N: usize>(&mut self, what: &str) -> Result<[u8; N], Stop> {
        self.skip(N, N, what)?;
        Ok(self.buf[self.pos - N..self.pos]
            .try_into()
            .expect("N bytes"))
    }

    fn u32(&mut self, what: &str) -> Result<u32, Stop> {
        let b = self.bytes::<4>(what)?;
        Ok(if self.le {
            u32::from_le_bytes(b)
        } else {
            u32::from_be_bytes(b)
        })
    }

    fn prim(&mut self, p: Prim, what: &str) -> Result<f64, Stop> {
        macro_rules! num {
            ($t:ty, $n:literal) => {{
                let b = self.bytes::<$n>(what)?;
                (if self.le {
                    <$t>::from_le_bytes(b)
                } else {
                    <$t>::from_be_bytes(b)
                }) as f64
            }};
        }
        Ok(match p {
            Prim::Bool | Prim::U8 => num!(u8, 1),
            Prim::I8 => num!(i8, 1),
            Prim::I16 => num!(i16, 2),
            Prim::U16 => num!(u16, 2),
            Prim::I32 => num!(i32, 4),
            Prim::U32 => num!(u32, 4),
            Prim::I64 => num!(i64, 8),
            Prim::U64 => num!(u64, 8),
            Prim::F32 => num!(f32, 4),
            Prim::F64 => num!(f64, 8),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TWIST: &str = "std_msgs/Header header\ngeometry_msgs/Twist twist\n\
================================================================================\n\
MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n\
================================================================================\n\
MSG: geometry_msgs/Twist\nVector3  linear\nVector3  angular\n\
================================================================================\n\
MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n";

    fn paths(p: &[&str]) -> Vec<FieldPath> {
        p.iter().map(|s| FieldPath::parse(s).unwrap()).collect()
    }

    /// A little-endian TwistStamped: stamp (7 s, 5 ns), frame "radar", linear (1, 2, 3).
    fn twist_payload(le: bool) -> Vec<u8> {
        let mut b = vec![0u8, le as u8, 0, 0];
        let mut body: Vec<u8> = Vec::new();
        let put = |body: &mut Vec<u8>, bytes: &[u8], align: usize| {
            while !body.len().is_multiple_of(align) {
                body.push(0);
            }
            body.extend_from_slice(bytes);
        };
        macro_rules! e {
            ($x:expr) => {
                if le {
                    $x.to_le_bytes()
                } else {
                    $x.to_be_bytes()
                }
            };
        }
        put(&mut body, &e!(7i32), 4);
        put(&mut body, &e!(5u32), 4);
        put(&mut body, &e!(6u32), 4);
        put(&mut body, b"radar\0", 1);
        for x in [1.0f64, 2.0, 3.0, 0.0, 0.0, 0.5] {
            put(&mut body, &e!(x), 8);
        }
        b.extend(body);
        b
    }

    #[test]
    fn reads_nested_fields_and_the_header_stamp_in_both_byte_orders() {
        for le in [true, false] {
            let d = Decoder::new(
                "geometry_msgs/msg/TwistStamped",
                TWIST.as_bytes(),
                &paths(&["twist.linear.x", "twist.angular.z", "twist.linear.y"]),
                true,
            )
            .unwrap();
            let mut found = [None; 12];
            d.extract(&twist_payload(le), &mut found).unwrap();
            assert_eq!(&found[..3], &[Some(1.0), Some(0.5), Some(2.0)]);
            assert_eq!(found[STAMP_SLOTS.0], Some(7.0));
            assert_eq!(found[STAMP_SLOTS.1], Some(5.0));
            assert_eq!(d.decode_all(&twist_payload(le)).unwrap(), 8);
        }
    }

    #[test]
    fn bad_paths_list_the_fields_that_exist() {
        let e = Decoder::new(
            "geometry_msgs/TwistStamped",
            TWIST.as_bytes(),
            &paths(&["twist.linear.w"]),
            false,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("geometry_msgs/Vector3 has no field \"w\"; its fields: float64 x, float64 y, float64 z"), "{e}");
        let e = Decoder::new(
            "geometry_msgs/TwistStamped",
            TWIST.as_bytes(),
            &paths(&["header.frame_id"]),
            false,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("is a string, not a number"), "{e}");
        let e = Decoder::new(
            "geometry_msgs/TwistStamped",
            TWIST.as_bytes(),
            &paths(&["twist"]),
            false,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("is a message"), "{e}");
        let e = Decoder::new("a/B", b"float64[] v\n", &paths(&["v"]), false)
            .unwrap_err()
            .to_string();
        assert!(e.contains("pick an element, e.g. v[0]"), "{e}");
        let e = Decoder::new("a/B", b"geometry_msgs/Point p\n", &paths(&["p.x"]), false)
            .unwrap_err()
            .to_string();
        assert!(e.contains("no definition of geometry_msgs/Point"), "{e}");
    }

    #[test]
    fn schemas_that_would_loop_or_recurse_without_bound_are_refused() {
        let sep = "=".repeat(80);
        let e = Decoder::new(
            "a/A",
            format!("B b\n{sep}\nMSG: a/B\nA a\n").as_bytes(),
            &[],
            false,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("contains itself"), "{e}");
        let mut deep = String::from("M0 m\n");
        for k in 0..100 {
            deep.push_str(&format!("{sep}\nMSG: a/M{k}\nM{} m\n", k + 1));
        }
        deep.push_str(&format!("{sep}\nMSG: a/M100\nfloat64 x\n"));
        let e = Decoder::new("a/Top", deep.as_bytes(), &[], false)
            .unwrap_err()
            .to_string();
        assert!(e.contains("nested deeper than 64"), "{e}");
        let e = Decoder::new("a/Z", b"int32[0] nothing\n", &[], false)
            .unwrap_err()
            .to_string();
        assert!(e.contains("serialises to no bytes"), "{e}");
        // A diamond-shaped schema 40 levels deep is checked in linear time.
        let mut diamond = String::from("D0 l\nD0 r\n");
        for k in 0..40 {
            diamond.push_str(&format!("{sep}\nMSG: a/D{k}\nD{n} l\nD{n} r\n", n = k + 1));
        }
        diamond.push_str(&format!("{sep}\nMSG: a/D40\nuint8 x\n"));
        assert!(Decoder::new("a/Top", diamond.as_bytes(), &[], false).is_ok());
        // A corrupt sequence count is an error, not four billion iterations.
        let d = Decoder::new(
            "a/S",
            b"geometry_msgs/Vector3[] v\nfloat64 after\n",
            &[],
            false,
        );
        assert!(d.is_err()); // no definition of Vector3
        let d = Decoder::new(
            "a/S",
            format!("Inner[] v\nfloat64 after\n{sep}\nMSG: a/Inner\nuint8 x\n").as_bytes(),
            &paths(&["after"]),
            false,
        )
        .unwrap();
        let mut p = vec![0u8, 1, 0, 0];
        p.extend(u32::MAX.to_le_bytes());
        p.extend([0u8; 16]);
        let e = d.extract(&p, &mut [None; 12]).unwrap_err().to_string();
        assert!(
            e.contains("4294967295 element(s), more than the 16 byte(s) left"),
            "{e}"
        );
    }

    #[test]
    fn sequences_strings_and_truncation() {
        // JointState-like: string[] name, float64[] velocity.
        let d = Decoder::new(
            "sensor_msgs/JointState",
            b"string[] name\nfloat64[] velocity\nint32 FLAG=3 # a constant\n",
            &paths(&["velocity[1]"]),
            false,
        )
        .unwrap();
        let mut p = vec![0u8, 1, 0, 0];
        p.extend(2u32.to_le_bytes());
        p.extend(3u32.to_le_bytes());
        p.extend(b"a1\0");
        p.push(0); // align
        p.extend(4u32.to_le_bytes());
        p.extend(b"abc\0");
        p.extend(2u32.to_le_bytes()); // body bytes 20..24: the doubles start 8-aligned
        p.extend(10.0f64.to_le_bytes());
        p.extend(20.0f64.to_le_bytes());
        let mut found = [None; 12];
        d.extract(&p, &mut found).unwrap();
        assert_eq!(found[0], Some(20.0));
        let e = d
            .extract(&p[..p.len() - 3], &mut found)
            .unwrap_err()
            .to_string();
        assert!(e.contains("message ends at byte"), "{e}");
        // A string longer than the message.
        let mut q = vec![0u8, 1, 0, 0];
        q.extend(1u32.to_le_bytes());
        q.extend(1000u32.to_le_bytes());
        q.extend(b"xx");
        let e = d.extract(&q, &mut found).unwrap_err().to_string();
        assert!(e.contains("needs 1000 byte(s) at byte 12"), "{e}");
        let e = d
            .extract(&[0, 7, 0, 0], &mut found)
            .unwrap_err()
            .to_string();
        assert!(e.contains("XCDR2"), "{e}");
    }
}
