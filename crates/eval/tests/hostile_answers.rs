//! The decoder of server bytes (`dexjoco_eval::decode`) under generated hostile input,
//! as trusted parsers are tested here (`dexjoco_testkit::hostile`: fixed seed, fixed case
//! count, no persistence files, a hang counts as a failure): arbitrary bytes, valid
//! answers and metadata mutated byte by byte, and numpy arrays with arbitrary dtypes,
//! shapes and data. Each case must return (a chunk or a named error), never panic or
//! hang, and the decoder's peak heap use, measured by the global allocator, must stay
//! within a small multiple of the message's size. The inputs that crashed `eval` before
//! (issue #44) are kept as regression cases (and as unit tests in `src/decode/tests.rs`).

use std::alloc::System;
use std::sync::Mutex;

use dexjoco_eval::decode::{Limits, MAX_ROWS, decode_answer, decode_metadata};
use dexjoco_eval::wire::{self, NdArray, encode};
use dexjoco_testkit::hostile::{apply_bytes, byte_edits, run_cases};
use peakmem_alloc::{INSTRUMENTED_SYSTEM, PeakMemAlloc, PeakMemAllocTrait};
use proptest::prelude::*;
use rmpv::Value;

#[global_allocator]
static HEAP: &PeakMemAlloc<System> = &INSTRUMENTED_SYSTEM;

/// One measurement at a time: the allocator's peak is the process's.
static MEASURING: Mutex<()> = Mutex::new(());

/// Peak heap bytes an answer's decoding may take: the chunk's values as `f64` rows (8
/// bytes per value, however small its dtype, plus a row's header) and a fixed allowance.
fn answer_budget(len: usize) -> usize {
    10 * len + 64 * 1024
}

/// Peak heap bytes the metadata's decoding may take: its JSON (a value per byte at most,
/// and never more than the decoder's value budget allows).
fn metadata_budget(len: usize) -> usize {
    (100 * len).min(16 << 20) + 64 * 1024
}

/// Decodes `bytes` as an answer for both arm setups and as metadata, within the budgets.
fn decode_within_bounds(bytes: &[u8]) -> Result<(), String> {
    let _one = MEASURING.lock().unwrap_or_else(|e| e.into_inner());
    for width in [22, 44] {
        let limits = Limits::for_width(width);
        HEAP.reset_peak_memory();
        let chunk = decode_answer(bytes, &limits);
        let peak = HEAP.get_peak_memory();
        if let Ok(rows) = &chunk {
            let ok = !rows.is_empty()
                && rows.len() <= MAX_ROWS
                && rows
                    .iter()
                    .all(|r| r.len() == width && r.iter().all(|v| v.is_finite()));
            if !ok {
                return Err(format!("an invalid chunk passed: {rows:?}"));
            }
        }
        drop(chunk);
        if peak > answer_budget(bytes.len()) {
            return Err(format!(
                "answer of {} bytes: peak heap {peak} bytes",
                bytes.len()
            ));
        }
    }
    HEAP.reset_peak_memory();
    let meta = decode_metadata(bytes);
    let peak = HEAP.get_peak_memory();
    drop(meta);
    if peak > metadata_budget(bytes.len()) {
        return Err(format!(
            "metadata of {} bytes: peak heap {peak} bytes",
            bytes.len()
        ));
    }
    Ok(())
}

/// An answer as openpi's `msgpack_numpy` packs it, the array's parts given raw, with an
/// extra key as openpi's server adds.
fn answer(dtype: &str, shape: &[usize], data: Vec<u8>) -> Vec<u8> {
    let shape = shape.to_vec();
    let mut answer = wire::answer(&NdArray {
        dtype: dtype.into(),
        shape,
        data,
    });
    let timing = Value::Map(vec![(Value::from("infer_ms"), Value::F64(12.5))]);
    if let Value::Map(m) = &mut answer {
        m.push((Value::from("server_timing"), timing));
    }
    encode(&answer)
}

/// Valid answers (both widths, several dtypes) and a valid metadata map.
fn valid_messages() -> Vec<Vec<u8>> {
    let mut out = Vec::new();
    for (width, rows) in [(22usize, 30usize), (44, 5), (22, 1)] {
        let n = width * rows;
        let f8: Vec<u8> = (0..n)
            .flat_map(|i| (i as f64 * 0.01).to_le_bytes())
            .collect();
        let f4: Vec<u8> = (0..n).flat_map(|i| (i as f32).to_be_bytes()).collect();
        out.push(answer("<f8", &[rows, width], f8));
        out.push(answer(">f4", &[rows, width], f4));
        out.push(answer("|u1", &[rows, width], vec![3; n]));
    }
    out.push(encode(&Value::Map(vec![
        (Value::from("policy"), Value::from("pi05")),
        (
            Value::from("action_horizon"),
            Value::Array(vec![Value::from(50), Value::Nil]),
        ),
    ])));
    out
}

/// The answers that crashed or exhausted `eval` before (issue #44).
fn regressions() -> Vec<Vec<u8>> {
    vec![
        answer("|u1", &[30, 22], vec![0; 10]),
        answer("", &[30, 22], vec![]),
        answer("<f8", &[1_000_000_000_000, 0], vec![]),
        answer("<f8", &[1 << 32, 1 << 32], vec![]),
        vec![0xc0; 1 << 20],
        {
            let mut m = vec![0x81, 0xa1, b'x'];
            m.extend(std::iter::repeat_n(0x91, 1 << 20));
            m.push(0xc0);
            m
        },
    ]
}

#[test]
fn the_inputs_that_crashed_eval_are_named_errors_within_bounds() {
    for (i, bytes) in regressions().iter().enumerate() {
        decode_within_bounds(bytes).unwrap_or_else(|e| panic!("regression {i}: {e}"));
        assert!(
            decode_answer(bytes, &Limits::for_width(22)).is_err(),
            "regression {i}"
        );
    }
    // The valid messages decode (the answers as chunks, the map as metadata).
    let valid = valid_messages();
    for bytes in &valid[..valid.len() - 1] {
        let width = if decode_answer(bytes, &Limits::for_width(22)).is_ok() {
            22
        } else {
            44
        };
        assert!(decode_answer(bytes, &Limits::for_width(width)).is_ok());
    }
    assert!(decode_metadata(valid.last().unwrap()).is_ok());
}

#[test]
fn arbitrary_and_mutated_server_bytes_never_panic_or_exhaust_memory() {
    run_cases(
        "arbitrary bytes",
        1500,
        proptest::collection::vec(any::<u8>(), 0..2048),
        |bytes| decode_within_bounds(&bytes),
    );
    let bases = valid_messages();
    let n = bases.len();
    run_cases(
        "mutated valid messages",
        3000,
        (0..n, byte_edits(6)),
        move |(i, edits)| decode_within_bounds(&apply_bytes(&bases[i], &edits)),
    );
    let dtypes = prop_oneof![
        Just("<f8".to_owned()),
        Just("|u1".to_owned()),
        Just(">i2".to_owned()),
        Just("<f2".to_owned()),
        "[<>|=]?[a-zA-Z]?[0-9]{0,3}",
    ];
    let dims = prop_oneof![
        0usize..64,
        Just(22usize),
        Just(44usize),
        Just(u32::MAX as usize + 1),
        Just(usize::MAX),
        any::<usize>(),
    ];
    run_cases(
        "arbitrary numpy arrays",
        3000,
        (
            dtypes,
            proptest::collection::vec(dims, 0..4),
            proptest::collection::vec(any::<u8>(), 0..1500),
        ),
        |(dtype, shape, data)| decode_within_bounds(&answer(&dtype, &shape, data)),
    );
}
