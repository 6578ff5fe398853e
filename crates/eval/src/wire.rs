//! openpi's wire format, our side: MessagePack in which numpy arrays are maps
//! `{b"__ndarray__": True, b"data": <bytes>, b"dtype": "<f8", b"shape": [..]}`
//! (`openpi_client.msgpack_numpy`). Observations are encoded as the reference client's
//! packer encodes them, byte for byte: keys in the order it builds them, byte-string keys
//! as MessagePack `bin`, text as `str`. What the server sends back is read by
//! [`decode`](crate::decode) only.

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
}

/// A policy server's answer `{"actions": <array>}` as openpi's server packs one (for a
/// server written in Rust, such as the tests' hostile ones).
pub fn answer(actions: &NdArray) -> Value {
    Value::Map(vec![(Value::from("actions"), actions.to_value())])
}

/// A byte-string key, as Python's `b"..."` packs.
fn bin(s: &str) -> Value {
    Value::Binary(s.as_bytes().to_vec())
}

/// Encodes a value.
pub fn encode(v: &Value) -> Vec<u8> {
    let mut out = Vec::new();
    rmpv::encode::write_value(&mut out, v).expect("writing to a Vec cannot fail");
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_array_we_encode_reads_back_through_the_servers_decoder() {
        let a = NdArray::f64(vec![1, 22], &[1.5; 22]);
        let limits = crate::decode::Limits::for_width(22);
        let rows = crate::decode::decode_answer(&encode(&answer(&a)), &limits).unwrap();
        assert_eq!(rows, [vec![1.5; 22]]);
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
