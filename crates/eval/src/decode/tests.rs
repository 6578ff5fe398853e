//! The decoder on valid answers of every dtype and on each hostile answer seen from
//! servers: named errors, nothing allocated for what the bytes do not hold.

use super::*;
use crate::wire::{self, NdArray, encode};
use rmpv::Value;

/// An answer `{"actions": <ndarray>}` as openpi's `msgpack_numpy` packs it, with the
/// array's parts given raw.
fn answer(dtype: &str, shape: &[usize], data: Vec<u8>) -> Vec<u8> {
    let shape = shape.to_vec();
    encode(&wire::answer(&NdArray {
        dtype: dtype.into(),
        shape,
        data,
    }))
}

const ONE_ARM: Limits = Limits {
    width: 22,
    max_rows: MAX_ROWS,
};

fn f64s(values: &[f64]) -> Vec<u8> {
    values.iter().flat_map(|v| v.to_le_bytes()).collect()
}

#[test]
fn valid_answers_of_every_numeric_dtype_decode() {
    let values: Vec<f64> = (0..44).map(|i| i as f64 - 7.0).collect();
    let rows = decode_answer(&answer("<f8", &[2, 22], f64s(&values)), &ONE_ARM).unwrap();
    assert_eq!(rows.len(), 2);
    assert_eq!(rows[1][0], 15.0);
    let be: Vec<u8> = values
        .iter()
        .flat_map(|v| (*v as f32).to_be_bytes())
        .collect();
    assert_eq!(
        decode_answer(&answer(">f4", &[2, 22], be), &ONE_ARM).unwrap(),
        rows
    );
    let i2: Vec<u8> = values
        .iter()
        .flat_map(|v| (*v as i16).to_le_bytes())
        .collect();
    assert_eq!(
        decode_answer(&answer("<i2", &[2, 22], i2), &ONE_ARM).unwrap(),
        rows
    );
    // Half precision: 1.5 is 0x3e00, -2 is 0xc000.
    let h: Vec<u8> = [0x3e00u16, 0xc000]
        .repeat(11)
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    let r = decode_answer(&answer("<f2", &[1, 22], h), &ONE_ARM).unwrap();
    assert_eq!(&r[0][..2], &[1.5, -2.0]);
    let u1 = decode_answer(&answer("|u1", &[1, 22], vec![255; 22]), &ONE_ARM).unwrap();
    assert_eq!(u1[0][0], 255.0);
    // Other keys (openpi's server_timing) are skipped.
    let mut with_timing = Value::Map(vec![(
        Value::from("server_timing"),
        Value::Map(vec![(Value::from("infer_ms"), Value::F64(3.5))]),
    )]);
    let actions =
        rmpv::decode::read_value(&mut &answer("<f8", &[1, 22], f64s(&[0.0; 22]))[..]).unwrap();
    if let (Value::Map(m), Value::Map(a)) = (&mut with_timing, actions) {
        m.extend(a);
    }
    assert_eq!(
        decode_answer(&encode(&with_timing), &ONE_ARM)
            .unwrap()
            .len(),
        1
    );
}

#[test]
fn each_hostile_answer_is_a_named_error() {
    let cases: Vec<(&str, Vec<u8>, &str)> = vec![
        // One-byte dtype whose data is shorter than the shape needs (was a panic).
        (
            "short u1",
            answer("|u1", &[30, 22], vec![0; 10]),
            "needs 660 bytes of data, it has 10",
        ),
        // An empty dtype string (was a panic in split_at).
        ("empty dtype", answer("", &[30, 22], vec![]), "dtype ''"),
        // Shape (10^12, 0) with no data (was 24 TB asked for).
        (
            "huge rows",
            answer("<f8", &[1_000_000_000_000, 0], vec![]),
            "shape (1000000000000, 0)",
        ),
        // Shape (2^32, 2^32): the product wraps to 0 (was 103 GB asked for).
        (
            "wrapping",
            answer("<f8", &[1 << 32, 1 << 32], vec![]),
            "shape (4294967296, 4294967296)",
        ),
        (
            "too many rows",
            answer("<f8", &[1 << 40, 22], vec![]),
            "more than the 1024 rows",
        ),
        (
            "rank",
            answer("<f8", &[22], f64s(&[0.0; 22])),
            "not (horizon, width)",
        ),
        ("empty", answer("<f8", &[0, 22], vec![]), "no actions"),
        (
            "width",
            answer("<f8", &[30, 21], f64s(&[0.0; 630])),
            "shape (30, 21)",
        ),
        (
            "string dtype",
            answer("<U8", &[1, 22], vec![0; 704]),
            "dtype '<U8'",
        ),
        (
            "object dtype",
            answer("|O", &[1, 22], vec![0; 22]),
            "dtype '|O'",
        ),
        ("not msgpack", vec![0xc1], "reserved byte"),
        (
            "truncated",
            answer("<f8", &[1, 22], f64s(&[0.0; 22]))[..50].to_vec(),
            "ends at byte 50",
        ),
        (
            "trailing",
            [answer("<f8", &[1, 22], f64s(&[0.0; 22])), vec![0]].concat(),
            "1 bytes after",
        ),
        (
            "a list",
            encode(&Value::Array(vec![])),
            "not a map (it is an array)",
        ),
        (
            "no actions",
            encode(&Value::Map(vec![(Value::from("x"), Value::Nil)])),
            "no 'actions' (it has: x)",
        ),
        // A map claiming 2^32-1 entries in a few bytes.
        (
            "lying count",
            vec![0xdf, 0xff, 0xff, 0xff, 0xff, 0xc0],
            "a container of 4294967295 entries",
        ),
        // A string claiming 4 GB.
        (
            "lying string",
            vec![0x81, 0xdb, 0xff, 0xff, 0xff, 0xff],
            "4294967295 more bytes",
        ),
    ];
    for (name, bytes, expect) in cases {
        let e = decode_answer(&bytes, &ONE_ARM).unwrap_err().to_string();
        assert!(e.contains(expect), "{name}: {e}");
    }
    let mut nan = f64s(&[0.0; 44]);
    nan[8 * 26..8 * 27].copy_from_slice(&f64::NAN.to_le_bytes());
    let e = decode_answer(&answer("<f8", &[2, 22], nan), &ONE_ARM).unwrap_err();
    assert_eq!(e.to_string(), "row 1, column 4 is NaN");
}

#[test]
fn deep_and_wide_messages_are_walked_without_recursion_or_allocation() {
    // 1,000,000 nested one-element arrays under an unknown key, then actions.
    let mut deep = vec![0x82, 0xa1, b'x'];
    deep.extend(std::iter::repeat_n(0x91, 1_000_000));
    deep.push(0xc0);
    deep.extend(&answer("<f8", &[1, 22], f64s(&[0.0; 22]))[1..]);
    assert_eq!(decode_answer(&deep, &ONE_ARM).unwrap().len(), 1);
    // 4 MiB of nils in an array: skipped, and as metadata refused past the budget.
    let mut nils = vec![0xdd];
    nils.extend(4_194_304u32.to_be_bytes());
    nils.extend(std::iter::repeat_n(0xc0, 4_194_304));
    assert_eq!(decode_metadata(&nils).unwrap_err(), DecodeError::TooLarge);
    let e = decode_answer(&nils, &ONE_ARM).unwrap_err();
    assert_eq!(e, DecodeError::NotAMap("an array"));
}

#[test]
fn metadata_reads_as_json_with_small_arrays_whole() {
    let meta = Value::Map(vec![
        (Value::from("policy"), Value::from("act")),
        (
            Value::from("mean"),
            rmpv::decode::read_value(&mut &answer("<f8", &[1, 2], f64s(&[0.5, 1.5]))[..])
                .unwrap()
                .as_map()
                .unwrap()[0]
                .1
                .clone(),
        ),
        (Value::from("blob"), Value::Binary(vec![0; 9])),
    ]);
    let j = decode_metadata(&encode(&meta)).unwrap();
    assert_eq!(
        j,
        serde_json::json!({"policy": "act", "mean": [0.5, 1.5], "blob": "<9 bytes>"})
    );
}
