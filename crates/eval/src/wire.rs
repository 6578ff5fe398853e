//! openpi's wire format: MessagePack in which numpy arrays are maps
//! `{b"__ndarray__": True, b"data": <bytes>, b"dtype": "<f8", b"shape": [..]}` and numpy
//! scalars `{b"__npgeneric__": True, b"data": <value>, b"dtype": ".."}`
//! (`openpi_client.msgpack_numpy`). Observations are encoded as the reference client's
//! packer encodes them, byte for byte: keys in the order it builds them, byte-string keys
//! as MessagePack `bin`, text as `str`.

use rmpv::Value;

/// A numpy array as it travels: dtype string (`|u1`, `<f4`, `<f8`...), shape and the
/// raw little-endian bytes.
#[derive(Debug, Clone, PartialEq)]
pub struct NdArray {
    /// numpy's `dtype.str`.
    pub dtype: String,
    /// The shape.
    pub shape: Vec<usize>,
    /// `tobytes()`: C order, the dtype's byte order.
    pub data: Vec<u8>,
}

impl NdArray {
    /// An array of `uint8` (`|u1`), e.g. an image (H, W, 3).
    pub fn u8(shape: Vec<usize>, data: Vec<u8>) -> Self {
        Self {
            dtype: "|u1".into(),
            shape,
            data,
        }
    }

    /// An array of little-endian `float64` (`<f8`).
    pub fn f64(shape: Vec<usize>, values: &[f64]) -> Self {
        Self {
            dtype: "<f8".into(),
            shape,
            data: values.iter().flat_map(|v| v.to_le_bytes()).collect(),
        }
    }

    /// The values as `f64`, for float and integer dtypes of either byte order; `None`
    /// for other dtypes or a byte count that does not match the shape.
    pub fn to_f64(&self) -> Option<Vec<f64>> {
        let n: usize = self.shape.iter().product();
        let (order, kind) = self.dtype.split_at(1);
        let little = match order {
            "<" | "|" | "=" => true,
            ">" => false,
            _ => return None,
        };
        macro_rules! read {
            ($t:ty, $size:expr) => {{
                if self.data.len() != n * $size {
                    return None;
                }
                self.data
                    .chunks_exact($size)
                    .map(|c| {
                        let b: [u8; $size] = c.try_into().expect("chunk size");
                        (if little {
                            <$t>::from_le_bytes(b)
                        } else {
                            <$t>::from_be_bytes(b)
                        }) as f64
                    })
                    .collect()
            }};
        }
        Some(match kind {
            "f8" => read!(f64, 8),
            "f4" => read!(f32, 4),
            "f2" => return None,
            "i8" => read!(i64, 8),
            "i4" => read!(i32, 4),
            "u1" => self.data.iter().map(|&b| f64::from(b)).collect(),
            _ => return None,
        })
    }

    /// The MessagePack value `msgpack_numpy.pack_array` makes of it.
    pub fn to_value(&self) -> Value {
        Value::Map(vec![
            (bin("__ndarray__"), Value::Boolean(true)),
            (bin("data"), Value::Binary(self.data.clone())),
            (bin("dtype"), Value::String(self.dtype.as_str().into())),
            (
                bin("shape"),
                Value::Array(self.shape.iter().map(|&d| Value::from(d as u64)).collect()),
            ),
        ])
    }

    /// The array a `__ndarray__` map holds, when `v` is one.
    pub fn from_value(v: &Value) -> Option<Self> {
        let map = v.as_map()?;
        let get = |k: &str| {
            map.iter()
                .find(|(key, _)| key_is(key, k))
                .map(|(_, value)| value)
        };
        get("__ndarray__")?;
        let data = match get("data")? {
            Value::Binary(b) => b.clone(),
            _ => return None,
        };
        let dtype = get("dtype")?.as_str()?.to_owned();
        let shape = get("shape")?
            .as_array()?
            .iter()
            .map(|d| d.as_u64().map(|d| d as usize))
            .collect::<Option<Vec<_>>>()?;
        Some(Self { dtype, shape, data })
    }
}

/// A byte-string key, as Python's `b"..."` packs.
fn bin(s: &str) -> Value {
    Value::Binary(s.as_bytes().to_vec())
}

/// Whether a map key is `k`, as bytes or text.
pub fn key_is(key: &Value, k: &str) -> bool {
    match key {
        Value::Binary(b) => b == k.as_bytes(),
        Value::String(s) => s.as_str() == Some(k),
        _ => false,
    }
}

/// The value of key `k` of a map.
pub fn get<'a>(v: &'a Value, k: &str) -> Option<&'a Value> {
    v.as_map()?
        .iter()
        .find(|(key, _)| key_is(key, k))
        .map(|(_, value)| value)
}

/// Encodes a value.
pub fn encode(v: &Value) -> Vec<u8> {
    let mut out = Vec::new();
    rmpv::encode::write_value(&mut out, v).expect("writing to a Vec cannot fail");
    out
}

/// Decodes one value from `bytes` (all of them).
pub fn decode(bytes: &[u8]) -> Result<Value, String> {
    let mut r = bytes;
    let v = rmpv::decode::read_value(&mut r).map_err(|e| format!("not MessagePack: {e}"))?;
    if !r.is_empty() {
        return Err(format!("{} bytes after the message", r.len()));
    }
    Ok(v)
}

/// A value as JSON for records (arrays as `{"dtype", "shape"}` summaries, bytes as their
/// length): what a server's metadata says, kept readable.
pub fn to_json(v: &Value) -> serde_json::Value {
    use serde_json::json;
    if let Some(a) = NdArray::from_value(v) {
        return match a.to_f64().filter(|x| x.len() <= 64) {
            Some(x) => json!(x),
            None => json!({"dtype": a.dtype, "shape": a.shape}),
        };
    }
    if let Some(g) = get(v, "__npgeneric__").and(get(v, "data")) {
        return to_json(g);
    }
    match v {
        Value::Nil => serde_json::Value::Null,
        Value::Boolean(b) => json!(b),
        Value::Integer(i) => i.as_i64().map_or_else(|| json!(i.as_u64()), |x| json!(x)),
        Value::F32(x) => json!(x),
        Value::F64(x) => json!(x),
        Value::String(s) => json!(s.as_str().unwrap_or("<not utf-8>")),
        Value::Binary(b) => json!(format!("<{} bytes>", b.len())),
        Value::Array(a) => serde_json::Value::Array(a.iter().map(to_json).collect()),
        Value::Map(m) => {
            let mut o = serde_json::Map::new();
            for (k, x) in m {
                let key = match k {
                    Value::String(s) => s.as_str().unwrap_or("?").to_owned(),
                    Value::Binary(b) => String::from_utf8_lossy(b).into_owned(),
                    other => other.to_string(),
                };
                o.insert(key, to_json(x));
            }
            serde_json::Value::Object(o)
        }
        Value::Ext(t, b) => json!(format!("<ext {t}: {} bytes>", b.len())),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_array_round_trips_and_reads_as_f64_in_any_float_dtype() {
        let a = NdArray::f64(vec![2, 2], &[1.0, -2.5, 3.25, 4.0]);
        let v = a.to_value();
        let back = NdArray::from_value(&decode(&encode(&v)).unwrap()).unwrap();
        assert_eq!(back, a);
        assert_eq!(back.to_f64().unwrap(), [1.0, -2.5, 3.25, 4.0]);
        let f32s = NdArray {
            dtype: "<f4".into(),
            shape: vec![2],
            data: [0.5f32, 2.0].iter().flat_map(|v| v.to_le_bytes()).collect(),
        };
        assert_eq!(f32s.to_f64().unwrap(), [0.5, 2.0]);
        let big = NdArray {
            dtype: ">f8".into(),
            shape: vec![1],
            data: 7.0f64.to_be_bytes().to_vec(),
        };
        assert_eq!(big.to_f64().unwrap(), [7.0]);
        // A byte count that disagrees with the shape is no array of numbers.
        let short = NdArray {
            dtype: "<f8".into(),
            shape: vec![3],
            data: vec![0; 16],
        };
        assert!(short.to_f64().is_none());
    }

    #[test]
    fn the_encoding_is_msgpack_numpys() {
        // msgpack_numpy.packb(np.array([1.0])) from openpi_client 0.1.2.
        let expected: &[u8] = &[
            0x84, 0xc4, 0x0b, b'_', b'_', b'n', b'd', b'a', b'r', b'r', b'a', b'y', b'_', b'_',
            0xc3, 0xc4, 0x04, b'd', b'a', b't', b'a', 0xc4, 0x08, 0, 0, 0, 0, 0, 0, 0xf0, 0x3f,
            0xc4, 0x05, b'd', b't', b'y', b'p', b'e', 0xa3, b'<', b'f', b'8', 0xc4, 0x05, b's',
            b'h', b'a', b'p', b'e', 0x91, 0x01,
        ];
        assert_eq!(encode(&NdArray::f64(vec![1], &[1.0]).to_value()), expected);
    }
}
