//! Everything a policy server sends, decoded from its bytes with bounds: the metadata it
//! sends first (kept as JSON in the records) and each answer, down to a validated action
//! chunk. Nothing else in the crate reads server bytes.
//!
//! Server bytes are untrusted. Every length, count, shape and dtype is checked against
//! the bytes that remain and against limits derived from the task (the action width, a
//! maximum horizon) before anything is allocated; arithmetic on sizes is checked; the
//! walk over values the decoder does not keep is iterative (no recursion that a deeply
//! nested message could overflow) and builds nothing. What is built is the chunk's own
//! values (at most [`MAX_ROWS`] x the width) and, for the metadata, a JSON summary of at
//! most [`MAX_METADATA_VALUES`] values, so the decoder's memory stays a small multiple
//! of the message's size whatever the message holds.
//!
//! MessagePack markers are classified with `rmp`; numpy arrays are openpi's
//! `msgpack_numpy` maps `{__ndarray__: True, data: <bytes>, dtype: "<f8", shape: [..]}`.

use rmp::Marker;
use serde_json::json;

/// The most rows (the horizon) an answer's chunk may have: openpi's policies answer 10 to
/// 50, the reference's evaluation asks for 30.
pub const MAX_ROWS: usize = 1024;

/// The most values the metadata may hold (a policy's metadata is a small map).
pub const MAX_METADATA_VALUES: usize = 65_536;

/// The deepest nesting of the metadata's maps and arrays.
pub const MAX_METADATA_DEPTH: usize = 64;

/// Arrays of at most this many numbers are kept whole in the metadata's JSON; larger ones
/// as their dtype and shape.
const INLINE_ARRAY: u64 = 64;

/// What an answer must be for the task: its chunk's width and the most rows it may have.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Limits {
    /// Values per row: the policy's action layout (22 per arm).
    pub width: usize,
    /// The most rows.
    pub max_rows: usize,
}

impl Limits {
    /// The limits for a policy of `width` values per action ([`MAX_ROWS`] rows at most).
    pub fn for_width(width: usize) -> Self {
        Self {
            width,
            max_rows: MAX_ROWS,
        }
    }
}

/// Why server bytes were refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum DecodeError {
    /// The bytes are not one MessagePack value.
    #[error("not MessagePack: {0}")]
    Malformed(String),
    /// The answer is not a map.
    #[error("the answer is not a map (it is {0})")]
    NotAMap(&'static str),
    /// The answer has no `actions`.
    #[error("the answer has no 'actions' (it has: {0})")]
    NoActions(String),
    /// `actions` is given more than once.
    #[error("the answer gives 'actions' twice")]
    DuplicateActions,
    /// `actions` is not a numpy array map.
    #[error("'actions' is not a numpy array: {0}")]
    NotAnArray(String),
    /// A dtype that is not a number type.
    #[error("'actions' has dtype '{0}', not a numeric numpy dtype (<f8, <f4, <f2, <i8, |u1...)")]
    Dtype(String),
    /// A shape that is not (horizon, width).
    #[error("'actions' has shape {0}, not (horizon, width)")]
    Rank(String),
    /// No rows.
    #[error("no actions (shape (0, {0}))")]
    Empty(u64),
    /// Rows of the wrong width.
    #[error(
        "shape ({rows}, {width}); {arms} policy answers ({rows}, {expected}): xyz, rotation vector and \
         16 hand joints per arm"
    )]
    Width {
        /// Rows given.
        rows: u64,
        /// Width given.
        width: u64,
        /// The width the task's policy has.
        expected: usize,
        /// "a one-arm" or "a two-arm".
        arms: &'static str,
    },
    /// More rows than a chunk may have.
    #[error("shape ({rows}, {width}): more than the {max} rows a chunk may have")]
    TooManyRows {
        /// Rows given.
        rows: u64,
        /// Width given.
        width: u64,
        /// The limit.
        max: usize,
    },
    /// The data's byte count disagrees with the shape and dtype.
    #[error(
        "'actions' of shape ({rows}, {width}) and dtype {dtype} needs {need} bytes of data, it has {got}"
    )]
    ByteCount {
        /// Rows.
        rows: u64,
        /// Width.
        width: u64,
        /// The dtype.
        dtype: String,
        /// Bytes the shape needs.
        need: u64,
        /// Bytes given.
        got: usize,
    },
    /// A value that is NaN or infinite.
    #[error("row {row}, column {column} is {value}")]
    NotFinite {
        /// Row.
        row: usize,
        /// Column.
        column: usize,
        /// The value.
        value: f64,
    },
    /// The metadata is larger than a policy's metadata is.
    #[error("more than {MAX_METADATA_VALUES} values, or nested deeper than {MAX_METADATA_DEPTH}")]
    TooLarge,
}

/// Decodes an answer into its action chunk (rows of `limits.width` finite values, at least
/// one and at most `limits.max_rows`). Keys other than `actions` are skipped.
pub fn decode_answer(bytes: &[u8], limits: &Limits) -> Result<Vec<Vec<f64>>, DecodeError> {
    let mut r = Reader::new(bytes);
    let entries = match r.head()? {
        Head::Map(n) => n,
        other => return Err(DecodeError::NotAMap(other.kind())),
    };
    let mut chunk = None;
    let mut keys = Vec::new();
    for _ in 0..entries {
        let key = r.head()?;
        if key.text() == Some(b"actions".as_slice()) {
            if chunk.is_some() {
                return Err(DecodeError::DuplicateActions);
            }
            let array = read_ndarray(&mut r)?;
            chunk = Some(array.chunk(limits)?);
        } else {
            if keys.len() < 16 {
                keys.push(key.describe());
            }
            r.skip_after(key)?;
            r.skip(1)?;
        }
    }
    r.finish()?;
    chunk.ok_or_else(|| DecodeError::NoActions(keys.join(", ")))
}

/// Decodes the server's metadata into JSON for the records: numpy arrays of at most 64
/// numbers as their values, larger ones as `{"dtype", "shape"}`, numpy scalars as their
/// value, bytes as `"<n bytes>"`.
pub fn decode_metadata(bytes: &[u8]) -> Result<serde_json::Value, DecodeError> {
    let mut r = Reader::new(bytes);
    let mut budget = MAX_METADATA_VALUES;
    let v = r.json(0, &mut budget)?;
    r.finish()?;
    Ok(v)
}

/// A numpy array's parts, borrowed from the message.
#[derive(Debug, Default)]
struct RawArray<'a> {
    data: Option<&'a [u8]>,
    dtype: Option<&'a [u8]>,
    shape: Option<Vec<u64>>,
    flagged: bool,
}

/// The most dimensions numpy allows.
const MAX_DIMS: u32 = 64;

/// Reads a `__ndarray__` map.
fn read_ndarray<'a>(r: &mut Reader<'a>) -> Result<RawArray<'a>, DecodeError> {
    let entries = match r.head()? {
        Head::Map(n) => n,
        other => return Err(DecodeError::NotAnArray(format!("it is {}", other.kind()))),
    };
    let mut a = RawArray::default();
    for _ in 0..entries {
        let key = r.head()?;
        match key.text() {
            Some(b"__ndarray__") => {
                a.flagged = true;
                r.skip(1)?;
            }
            Some(b"data") => match r.head()? {
                Head::Bin(b) | Head::Str(b) => a.data = Some(b),
                other => {
                    return Err(DecodeError::NotAnArray(format!(
                        "its data is {}",
                        other.kind()
                    )));
                }
            },
            Some(b"dtype") => match r.head()? {
                Head::Str(s) | Head::Bin(s) => a.dtype = Some(s),
                other => {
                    return Err(DecodeError::NotAnArray(format!(
                        "its dtype is {}",
                        other.kind()
                    )));
                }
            },
            Some(b"shape") => a.shape = Some(read_shape(r)?),
            _ => {
                r.skip_after(key)?;
                r.skip(1)?;
            }
        }
    }
    if !a.flagged {
        return Err(DecodeError::NotAnArray("no '__ndarray__' key".into()));
    }
    Ok(a)
}

/// Reads a shape: an array of at most [`MAX_DIMS`] non-negative integers.
fn read_shape(r: &mut Reader<'_>) -> Result<Vec<u64>, DecodeError> {
    let n = match r.head()? {
        Head::Array(n) if n <= MAX_DIMS => n,
        Head::Array(n) => return Err(DecodeError::Rank(format!("of {n} dimensions"))),
        other => return Err(DecodeError::Rank(format!("'{}'", other.kind()))),
    };
    (0..n)
        .map(|_| match r.head()? {
            Head::Uint(d) => Ok(d),
            Head::Int(d) if d >= 0 => Ok(d as u64),
            other => Err(DecodeError::Rank(format!(
                "with a dimension that is {}",
                other.describe()
            ))),
        })
        .collect()
}

/// A numeric dtype: its kind, item size and byte order.
#[derive(Debug, Clone, Copy)]
struct Dtype {
    kind: u8,
    size: usize,
    little: bool,
}

impl Dtype {
    /// numpy's `dtype.str` of a number type (`<f8`, `>i4`, `|u1`, `=f2`...).
    fn parse(s: &[u8]) -> Option<Self> {
        let [order, kind, size] = s else { return None };
        let little = match order {
            b'<' | b'|' | b'=' => true,
            b'>' => false,
            _ => return None,
        };
        let size = usize::from(size.checked_sub(b'0')?);
        let ok = match kind {
            b'f' => matches!(size, 2 | 4 | 8),
            b'i' | b'u' => matches!(size, 1 | 2 | 4 | 8),
            _ => false,
        };
        ok.then_some(Self {
            kind: *kind,
            size,
            little,
        })
    }

    /// One value from its `size` bytes.
    fn value(&self, b: &[u8]) -> f64 {
        let mut buf = [0u8; 8];
        // Big-endian bytes reversed read as little-endian.
        for (i, &x) in b.iter().enumerate() {
            buf[if self.little { i } else { b.len() - 1 - i }] = x;
        }
        let bits = u64::from_le_bytes(buf);
        match (self.kind, self.size) {
            (b'f', 8) => f64::from_bits(bits),
            (b'f', 4) => f64::from(f32::from_bits(bits as u32)),
            (b'f', _) => half_to_f64(bits as u16),
            (b'u', _) => bits as f64,
            (_, size) => {
                // Sign-extend the low `size` bytes.
                let shift = 64 - 8 * size as u32;
                ((bits << shift) as i64 >> shift) as f64
            }
        }
    }
}

/// An IEEE 754 half-precision value.
fn half_to_f64(h: u16) -> f64 {
    let sign = if h & 0x8000 != 0 { -1.0 } else { 1.0 };
    let exp = i32::from((h >> 10) & 0x1f);
    let frac = f64::from(h & 0x3ff);
    sign * match exp {
        0 => frac * 2f64.powi(-24),
        31 if frac == 0.0 => f64::INFINITY,
        31 => f64::NAN,
        e => (1024.0 + frac) * 2f64.powi(e - 25),
    }
}

impl RawArray<'_> {
    /// The array as a validated chunk: shape, width, row count and byte count checked
    /// before any value is read.
    fn chunk(&self, limits: &Limits) -> Result<Vec<Vec<f64>>, DecodeError> {
        let missing = |what: &str| DecodeError::NotAnArray(format!("no '{what}'"));
        let data = self.data.ok_or_else(|| missing("data"))?;
        let dtype_bytes = self.dtype.ok_or_else(|| missing("dtype"))?;
        let shape = self.shape.as_ref().ok_or_else(|| missing("shape"))?;
        let dtype_text = String::from_utf8_lossy(&dtype_bytes[..dtype_bytes.len().min(32)]);
        let dtype =
            Dtype::parse(dtype_bytes).ok_or_else(|| DecodeError::Dtype(dtype_text.to_string()))?;
        let &[rows, width] = shape.as_slice() else {
            return Err(DecodeError::Rank(format!("{shape:?}")));
        };
        if width != limits.width as u64 {
            return Err(DecodeError::Width {
                rows,
                width,
                expected: limits.width,
                arms: if limits.width > 22 {
                    "a two-arm"
                } else {
                    "a one-arm"
                },
            });
        }
        if rows == 0 {
            return Err(DecodeError::Empty(width));
        }
        if rows > limits.max_rows as u64 {
            return Err(DecodeError::TooManyRows {
                rows,
                width,
                max: limits.max_rows,
            });
        }
        let need = rows
            .checked_mul(width)
            .and_then(|n| n.checked_mul(dtype.size as u64));
        if need != Some(data.len() as u64) {
            return Err(DecodeError::ByteCount {
                rows,
                width,
                dtype: dtype_text.to_string(),
                need: need.unwrap_or(u64::MAX),
                got: data.len(),
            });
        }
        let (rows, width) = (rows as usize, width as usize);
        let mut out = Vec::with_capacity(rows);
        for (i, row) in data.chunks_exact(width * dtype.size).enumerate() {
            let values: Vec<f64> = row
                .chunks_exact(dtype.size)
                .map(|b| dtype.value(b))
                .collect();
            if let Some(c) = values.iter().position(|v| !v.is_finite()) {
                return Err(DecodeError::NotFinite {
                    row: i,
                    column: c,
                    value: values[c],
                });
            }
            out.push(values);
        }
        Ok(out)
    }
}

/// One MessagePack value's head: scalars whole, strings and bytes borrowed, containers as
/// their entry counts (the entries follow).
#[derive(Debug, Clone, Copy)]
enum Head<'a> {
    Nil,
    Bool(bool),
    Uint(u64),
    Int(i64),
    Float(f64),
    Str(&'a [u8]),
    Bin(&'a [u8]),
    Array(u32),
    Map(u32),
    Ext(&'a [u8]),
}

impl<'a> Head<'a> {
    /// The bytes of a text or byte-string key.
    fn text(&self) -> Option<&'a [u8]> {
        match self {
            Self::Str(s) | Self::Bin(s) => Some(s),
            _ => None,
        }
    }

    /// What kind of value, in words.
    fn kind(&self) -> &'static str {
        match self {
            Self::Nil => "nil",
            Self::Bool(_) => "a boolean",
            Self::Uint(_) | Self::Int(_) => "an integer",
            Self::Float(_) => "a float",
            Self::Str(_) => "a string",
            Self::Bin(_) => "bytes",
            Self::Array(_) => "an array",
            Self::Map(_) => "a map",
            Self::Ext(_) => "an extension value",
        }
    }

    /// A short description (a key's text, cut to 40 characters).
    fn describe(&self) -> String {
        match self.text() {
            Some(t) => String::from_utf8_lossy(&t[..t.len().min(40)]).into_owned(),
            None => self.kind().to_owned(),
        }
    }

    /// Values that follow this head as its entries.
    fn entries(&self) -> u64 {
        match self {
            Self::Array(n) => u64::from(*n),
            Self::Map(n) => 2 * u64::from(*n),
            _ => 0,
        }
    }
}

/// A cursor over the message's bytes; every read checked against what remains.
struct Reader<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Reader<'a> {
    fn new(bytes: &'a [u8]) -> Self {
        Self { bytes, pos: 0 }
    }

    fn remaining(&self) -> usize {
        self.bytes.len() - self.pos
    }

    fn truncated(&self, need: u64) -> DecodeError {
        DecodeError::Malformed(format!(
            "the message ends at byte {} where {need} more bytes were due",
            self.bytes.len()
        ))
    }

    /// The next `n` bytes.
    fn take(&mut self, n: u64) -> Result<&'a [u8], DecodeError> {
        if n > self.remaining() as u64 {
            return Err(self.truncated(n));
        }
        let s = &self.bytes[self.pos..self.pos + n as usize];
        self.pos += n as usize;
        Ok(s)
    }

    /// A big-endian unsigned integer of `n` (1, 2, 4, 8) bytes.
    fn be(&mut self, n: u64) -> Result<u64, DecodeError> {
        Ok(self
            .take(n)?
            .iter()
            .fold(0u64, |acc, &b| (acc << 8) | u64::from(b)))
    }

    /// A container's entry count, refused when the remaining bytes cannot hold that many
    /// entries (each takes at least one byte).
    fn count(&mut self, len_bytes: u64, per_entry: u64) -> Result<u32, DecodeError> {
        let n = self.be(len_bytes)?;
        self.fits(n, per_entry)
    }

    fn fits(&self, n: u64, per_entry: u64) -> Result<u32, DecodeError> {
        if n.saturating_mul(per_entry) > self.remaining() as u64 {
            return Err(DecodeError::Malformed(format!(
                "a container of {n} entries at byte {} where {} bytes remain",
                self.pos,
                self.remaining()
            )));
        }
        Ok(n as u32)
    }

    /// The next value's head.
    fn head(&mut self) -> Result<Head<'a>, DecodeError> {
        let at = self.pos;
        let byte = self.take(1)?[0];
        Ok(match Marker::from_u8(byte) {
            Marker::FixPos(v) => Head::Uint(u64::from(v)),
            Marker::FixNeg(v) => Head::Int(i64::from(v)),
            Marker::Null => Head::Nil,
            Marker::True => Head::Bool(true),
            Marker::False => Head::Bool(false),
            Marker::U8 => Head::Uint(self.be(1)?),
            Marker::U16 => Head::Uint(self.be(2)?),
            Marker::U32 => Head::Uint(self.be(4)?),
            Marker::U64 => Head::Uint(self.be(8)?),
            Marker::I8 => Head::Int(i64::from(self.be(1)? as u8 as i8)),
            Marker::I16 => Head::Int(i64::from(self.be(2)? as u16 as i16)),
            Marker::I32 => Head::Int(i64::from(self.be(4)? as u32 as i32)),
            Marker::I64 => Head::Int(self.be(8)? as i64),
            Marker::F32 => Head::Float(f64::from(f32::from_bits(self.be(4)? as u32))),
            Marker::F64 => Head::Float(f64::from_bits(self.be(8)?)),
            Marker::FixStr(n) => Head::Str(self.take(u64::from(n))?),
            Marker::Str8 => Head::Str(self.sized(1)?),
            Marker::Str16 => Head::Str(self.sized(2)?),
            Marker::Str32 => Head::Str(self.sized(4)?),
            Marker::Bin8 => Head::Bin(self.sized(1)?),
            Marker::Bin16 => Head::Bin(self.sized(2)?),
            Marker::Bin32 => Head::Bin(self.sized(4)?),
            Marker::FixArray(n) => Head::Array(self.fits(u64::from(n), 1)?),
            Marker::Array16 => Head::Array(self.count(2, 1)?),
            Marker::Array32 => Head::Array(self.count(4, 1)?),
            Marker::FixMap(n) => Head::Map(self.fits(u64::from(n), 2)?),
            Marker::Map16 => Head::Map(self.count(2, 2)?),
            Marker::Map32 => Head::Map(self.count(4, 2)?),
            Marker::FixExt1 => Head::Ext(self.take(2)?),
            Marker::FixExt2 => Head::Ext(self.take(3)?),
            Marker::FixExt4 => Head::Ext(self.take(5)?),
            Marker::FixExt8 => Head::Ext(self.take(9)?),
            Marker::FixExt16 => Head::Ext(self.take(17)?),
            Marker::Ext8 => Head::Ext(self.sized_ext(1)?),
            Marker::Ext16 => Head::Ext(self.sized_ext(2)?),
            Marker::Ext32 => Head::Ext(self.sized_ext(4)?),
            Marker::Reserved => {
                return Err(DecodeError::Malformed(format!(
                    "the reserved byte 0xc1 at byte {at}"
                )));
            }
        })
    }

    /// Bytes preceded by their length in `len_bytes` bytes.
    fn sized(&mut self, len_bytes: u64) -> Result<&'a [u8], DecodeError> {
        let n = self.be(len_bytes)?;
        self.take(n)
    }

    /// An extension value: its length, then its type byte and data.
    fn sized_ext(&mut self, len_bytes: u64) -> Result<&'a [u8], DecodeError> {
        let n = self.be(len_bytes)?;
        self.take(n.saturating_add(1))
    }

    /// Skips `n` whole values, iteratively.
    fn skip(&mut self, n: u64) -> Result<(), DecodeError> {
        let mut pending = n;
        while pending > 0 {
            pending -= 1;
            let h = self.head()?;
            pending = pending.saturating_add(h.entries());
        }
        Ok(())
    }

    /// Skips the entries of a head already read.
    fn skip_after(&mut self, head: Head<'_>) -> Result<(), DecodeError> {
        self.skip(head.entries())
    }

    /// Refuses bytes after the value.
    fn finish(&self) -> Result<(), DecodeError> {
        match self.remaining() {
            0 => Ok(()),
            n => Err(DecodeError::Malformed(format!(
                "{n} bytes after the message"
            ))),
        }
    }

    /// The next value as JSON, spending one of `budget` per value, at most
    /// [`MAX_METADATA_DEPTH`] deep.
    fn json(&mut self, depth: usize, budget: &mut usize) -> Result<serde_json::Value, DecodeError> {
        let head = self.head()?;
        self.json_of(head, depth, budget)
    }

    /// The value whose head was just read, as JSON.
    fn json_of(
        &mut self,
        head: Head<'a>,
        depth: usize,
        budget: &mut usize,
    ) -> Result<serde_json::Value, DecodeError> {
        if depth > MAX_METADATA_DEPTH || *budget == 0 {
            return Err(DecodeError::TooLarge);
        }
        *budget -= 1;
        Ok(match head {
            Head::Nil => serde_json::Value::Null,
            Head::Bool(b) => json!(b),
            Head::Uint(v) => json!(v),
            Head::Int(v) => json!(v),
            Head::Float(v) => json!(v),
            Head::Str(s) => json!(String::from_utf8_lossy(s)),
            Head::Bin(b) => json!(format!("<{} bytes>", b.len())),
            Head::Ext(b) => json!(format!("<extension value: {} bytes>", b.len() - 1)),
            Head::Array(n) => {
                let mut items = Vec::new();
                for _ in 0..n {
                    items.push(self.json(depth + 1, budget)?);
                }
                serde_json::Value::Array(items)
            }
            Head::Map(n) => {
                let mut map = serde_json::Map::new();
                let mut data = None;
                for _ in 0..n {
                    let key = match self.head()? {
                        k @ (Head::Str(_) | Head::Bin(_)) => k.describe(),
                        Head::Uint(v) => v.to_string(),
                        Head::Int(v) => v.to_string(),
                        other => {
                            self.skip_after(other)?;
                            other.kind().to_owned()
                        }
                    };
                    let value = self.head()?;
                    if let (Head::Bin(b), "data") = (value, key.as_str()) {
                        data = Some(b);
                    }
                    let value = self.json_of(value, depth + 1, budget)?;
                    map.insert(key, value);
                }
                numpy_summary(map, data)
            }
        })
    }
}

/// A map that is a numpy array or scalar, summarized: arrays of at most 64 numbers as
/// their values, others as `{"dtype", "shape"}`; scalars as their value. Other maps
/// unchanged.
fn numpy_summary(
    map: serde_json::Map<String, serde_json::Value>,
    data: Option<&[u8]>,
) -> serde_json::Value {
    if map.contains_key("__npgeneric__") {
        return map.get("data").cloned().unwrap_or_default();
    }
    if !map.contains_key("__ndarray__") {
        return serde_json::Value::Object(map);
    }
    let dtype = map.get("dtype").cloned().unwrap_or_default();
    let shape = map.get("shape").cloned().unwrap_or_default();
    let values = (|| {
        let t = Dtype::parse(dtype.as_str()?.as_bytes())?;
        let n = shape
            .as_array()?
            .iter()
            .try_fold(1u64, |n, d| n.checked_mul(d.as_u64()?))?;
        let data = data?;
        (n <= INLINE_ARRAY && n * t.size as u64 == data.len() as u64).then(|| {
            data.chunks_exact(t.size)
                .map(|b| t.value(b))
                .collect::<Vec<f64>>()
        })
    })();
    match values {
        Some(v) => json!(v),
        None => json!({"dtype": dtype, "shape": shape}),
    }
}

#[cfg(test)]
mod tests;
