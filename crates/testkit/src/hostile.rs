//! Hostile inputs, made by generation: `proptest` strategies that mutate valid files
//! (bytes, JSON values, text lines), and a bounded, deterministic runner that checks a
//! parser neither panics nor hangs on any of them.
//!
//! The runner uses a fixed case count, a fixed seed (ChaCha) and no failure-persistence
//! files, so every run tries the same cases; each case runs on its own thread and fails
//! the test when it takes longer than [`CASE_TIMEOUT`].

use std::time::{Duration, Instant};

use proptest::prelude::*;
use proptest::sample::Index;
use proptest::test_runner::{Config, RngAlgorithm, TestCaseError, TestRng, TestRunner};
use serde_json::Value;

/// The longest one case may take before it counts as a hang.
pub const CASE_TIMEOUT: Duration = Duration::from_secs(20);

/// Runs `check` on `cases` values drawn from `strategy` with a fixed seed; panics with
/// the (shrunk) failing value when `check` panics, returns an error, or hangs. Returns
/// the wall time taken.
pub fn run_cases<S, F>(name: &str, cases: u32, strategy: S, check: F) -> Duration
where
    S: Strategy,
    S::Value: Send + 'static,
    F: Fn(S::Value) -> Result<(), String> + Send + Sync + Clone + 'static,
{
    let config = Config {
        cases,
        failure_persistence: None,
        max_shrink_iters: 200,
        ..Config::default()
    };
    let rng = TestRng::deterministic_rng(RngAlgorithm::ChaCha);
    let mut runner = TestRunner::new_with_rng(config, rng);
    let t0 = Instant::now();
    let result = runner.run(&strategy, |value| {
        let check = check.clone();
        let (tx, rx) = std::sync::mpsc::channel();
        let worker = std::thread::Builder::new()
            .name("hostile-case".into())
            .spawn(move || {
                let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| check(value)));
                let _ = tx.send(r);
            })
            .expect("spawn a case thread");
        match rx.recv_timeout(CASE_TIMEOUT) {
            Ok(Ok(Ok(()))) => {
                let _ = worker.join();
                Ok(())
            }
            Ok(Ok(Err(msg))) => Err(TestCaseError::fail(msg)),
            Ok(Err(panic)) => {
                let msg = panic
                    .downcast_ref::<String>()
                    .cloned()
                    .or_else(|| panic.downcast_ref::<&str>().map(|s| (*s).to_owned()))
                    .unwrap_or_else(|| "a panic".into());
                Err(TestCaseError::fail(format!("panicked: {msg}")))
            }
            Err(_) => Err(TestCaseError::fail(format!(
                "no answer within {CASE_TIMEOUT:?}: a hang"
            ))),
        }
    });
    if let Err(e) = result {
        panic!("{name}: {e}");
    }
    t0.elapsed()
}

/// One edit of a byte string; positions are fractions of its length, so one edit list
/// applies to any input.
#[derive(Debug, Clone)]
pub enum ByteEdit {
    /// Flip one bit.
    Flip(Index, u8),
    /// Set one byte.
    Set(Index, u8),
    /// Write an integer (little endian) of 1, 2, 4 or 8 bytes, from a list of values
    /// parsers trip on (0, 1, -1, the largest...).
    Int(Index, usize, u64),
    /// Cut the data here.
    Truncate(Index),
    /// Insert bytes.
    Insert(Index, Vec<u8>),
    /// Remove up to this many bytes.
    Delete(Index, usize),
    /// Repeat a stretch of up to this many bytes.
    Duplicate(Index, usize),
}

/// Integers parsers trip on.
pub const INTERESTING: [u64; 12] = [
    0,
    1,
    2,
    0x7f,
    0xff,
    0x7fff,
    0xffff,
    0x7fff_ffff,
    0xffff_ffff,
    0x7fff_ffff_ffff_ffff,
    u64::MAX,
    1 << 40,
];

/// A strategy of one byte edit.
pub fn byte_edit() -> impl Strategy<Value = ByteEdit> {
    prop_oneof![
        3 => (any::<Index>(), 0u8..8).prop_map(|(i, b)| ByteEdit::Flip(i, b)),
        2 => (any::<Index>(), any::<u8>()).prop_map(|(i, v)| ByteEdit::Set(i, v)),
        3 => (any::<Index>(), prop::sample::select(vec![1usize, 2, 4, 8]),
              prop::sample::select(INTERESTING.to_vec()))
            .prop_map(|(i, w, v)| ByteEdit::Int(i, w, v)),
        1 => any::<Index>().prop_map(ByteEdit::Truncate),
        1 => (any::<Index>(), prop::collection::vec(any::<u8>(), 1..16))
            .prop_map(|(i, b)| ByteEdit::Insert(i, b)),
        1 => (any::<Index>(), 1usize..64).prop_map(|(i, n)| ByteEdit::Delete(i, n)),
        1 => (any::<Index>(), 1usize..64).prop_map(|(i, n)| ByteEdit::Duplicate(i, n)),
    ]
}

/// A strategy of 1 to `max` byte edits.
pub fn byte_edits(max: usize) -> impl Strategy<Value = Vec<ByteEdit>> {
    prop::collection::vec(byte_edit(), 1..=max)
}

/// Applies byte edits in order.
pub fn apply_bytes(data: &[u8], edits: &[ByteEdit]) -> Vec<u8> {
    let mut d = data.to_vec();
    for e in edits {
        let at = |i: &Index, extra: usize| {
            if d.is_empty() && extra == 0 {
                0
            } else {
                i.index(d.len() + extra)
            }
        };
        match e {
            ByteEdit::Flip(i, b) if !d.is_empty() => {
                let k = at(i, 0);
                d[k] ^= 1 << b;
            }
            ByteEdit::Set(i, v) if !d.is_empty() => {
                let k = at(i, 0);
                d[k] = *v;
            }
            ByteEdit::Int(i, w, v) if !d.is_empty() => {
                let k = at(i, 0);
                let bytes = v.to_le_bytes();
                for (j, b) in bytes[..*w].iter().enumerate() {
                    if let Some(x) = d.get_mut(k + j) {
                        *x = *b;
                    }
                }
            }
            ByteEdit::Truncate(i) => {
                let k = at(i, 1);
                d.truncate(k);
            }
            ByteEdit::Insert(i, b) => {
                let k = at(i, 1);
                d.splice(k..k, b.iter().copied());
            }
            ByteEdit::Delete(i, n) if !d.is_empty() => {
                let k = at(i, 0);
                let end = (k + n).min(d.len());
                d.drain(k..end);
            }
            ByteEdit::Duplicate(i, n) if !d.is_empty() => {
                let k = at(i, 0);
                let end = (k + n).min(d.len());
                let stretch = d[k..end].to_vec();
                d.splice(end..end, stretch);
            }
            _ => {}
        }
    }
    d
}

/// One edit of a JSON document: a value at some path (a fraction of the document's
/// paths) replaced, removed, or given a sibling.
#[derive(Debug, Clone)]
pub enum JsonEdit {
    /// Replace the value at the path.
    Replace(Index, Value),
    /// Remove the value at the path (the key, or the array element).
    Remove(Index),
    /// Add an unknown key to the object at (or holding) the path.
    AddKey(Index, String, Value),
    /// Repeat the element at the path in its array.
    DuplicateElement(Index),
}

/// JSON values parsers trip on: wrong types, extremes, empty and nested containers.
pub fn hostile_json_value() -> impl Strategy<Value = Value> {
    let leaf = prop_oneof![
        Just(Value::Null),
        any::<bool>().prop_map(Value::Bool),
        prop::sample::select(vec![
            0.0,
            -0.0,
            1.0,
            -1.0,
            0.5,
            1e-300,
            1e300,
            -1e300,
            f64::MAX,
            f64::MIN,
            1e20,
            4_294_967_296.0,
        ])
        .prop_map(|f| serde_json::json!(f)),
        prop::sample::select(INTERESTING.to_vec()).prop_map(|v| serde_json::json!(v)),
        prop::sample::select(vec![i64::MIN, -1, -2, -1024]).prop_map(|v| serde_json::json!(v)),
        prop::sample::select(vec![
            String::new(),
            "x".to_owned(),
            "<f8".to_owned(),
            "<f4".to_owned(),
            "|u1".to_owned(),
            "<i8".to_owned(),
            "C".to_owned(),
            "F".to_owned(),
            "/".to_owned(),
            "NaN".to_owned(),
            "\u{0}".to_owned(),
            "é\u{202e}".to_owned(),
        ])
        .prop_map(Value::String),
    ];
    leaf.prop_recursive(2, 8, 4, |inner| {
        prop_oneof![
            prop::collection::vec(inner.clone(), 0..4).prop_map(Value::Array),
            prop::collection::btree_map("[a-z_]{1,6}", inner, 0..3)
                .prop_map(|m| Value::Object(m.into_iter().collect())),
        ]
    })
}

/// A strategy of one JSON edit.
pub fn json_edit() -> impl Strategy<Value = JsonEdit> {
    prop_oneof![
        6 => (any::<Index>(), hostile_json_value()).prop_map(|(i, v)| JsonEdit::Replace(i, v)),
        2 => any::<Index>().prop_map(JsonEdit::Remove),
        1 => (any::<Index>(), "[a-z_]{1,8}", hostile_json_value())
            .prop_map(|(i, k, v)| JsonEdit::AddKey(i, k, v)),
        1 => any::<Index>().prop_map(JsonEdit::DuplicateElement),
    ]
}

/// A strategy of 1 to `max` JSON edits.
pub fn json_edits(max: usize) -> impl Strategy<Value = Vec<JsonEdit>> {
    prop::collection::vec(json_edit(), 1..=max)
}

/// A step of a path into a JSON value.
#[derive(Debug, Clone)]
enum Step {
    Key(String),
    Element(usize),
}

fn paths(v: &Value, prefix: &mut Vec<Step>, out: &mut Vec<Vec<Step>>) {
    out.push(prefix.clone());
    match v {
        Value::Object(m) => {
            for (k, x) in m {
                prefix.push(Step::Key(k.clone()));
                paths(x, prefix, out);
                prefix.pop();
            }
        }
        Value::Array(a) => {
            for (i, x) in a.iter().enumerate() {
                prefix.push(Step::Element(i));
                paths(x, prefix, out);
                prefix.pop();
            }
        }
        _ => {}
    }
}

fn at_mut<'a>(v: &'a mut Value, path: &[Step]) -> Option<&'a mut Value> {
    let mut cur = v;
    for s in path {
        cur = match (s, cur) {
            (Step::Key(k), Value::Object(m)) => m.get_mut(k)?,
            (Step::Element(i), Value::Array(a)) => a.get_mut(*i)?,
            _ => return None,
        };
    }
    Some(cur)
}

/// Applies JSON edits in order.
pub fn apply_json(doc: &Value, edits: &[JsonEdit]) -> Value {
    let mut doc = doc.clone();
    for e in edits {
        let mut all = Vec::new();
        paths(&doc, &mut Vec::new(), &mut all);
        let pick = |i: &Index| all[i.index(all.len())].clone();
        match e {
            JsonEdit::Replace(i, v) => {
                let p = pick(i);
                if let Some(x) = at_mut(&mut doc, &p) {
                    *x = v.clone();
                }
            }
            JsonEdit::Remove(i) => {
                let mut p = pick(i);
                let Some(last) = p.pop() else {
                    doc = Value::Null;
                    continue;
                };
                match (last, at_mut(&mut doc, &p)) {
                    (Step::Key(k), Some(Value::Object(m))) => {
                        m.remove(&k);
                    }
                    (Step::Element(n), Some(Value::Array(a))) if n < a.len() => {
                        a.remove(n);
                    }
                    _ => {}
                }
            }
            JsonEdit::AddKey(i, k, v) => {
                let mut p = pick(i);
                loop {
                    if let Some(Value::Object(m)) = at_mut(&mut doc, &p) {
                        m.insert(k.clone(), v.clone());
                        break;
                    }
                    if p.pop().is_none() {
                        break;
                    }
                }
            }
            JsonEdit::DuplicateElement(i) => {
                let mut p = pick(i);
                if let Some(Step::Element(n)) = p.pop()
                    && let Some(Value::Array(a)) = at_mut(&mut doc, &p)
                    && n < a.len()
                {
                    let x = a[n].clone();
                    a.insert(n, x);
                }
            }
        }
    }
    doc
}

/// One edit of a text file, line by line.
#[derive(Debug, Clone)]
pub enum LineEdit {
    /// Remove a line.
    Remove(Index),
    /// Repeat a line.
    Duplicate(Index),
    /// Swap a line with the next.
    Swap(Index),
    /// Replace what follows the first `=` or `,` of a line (a value) with this text.
    Value(Index, String),
    /// Insert a line.
    Insert(Index, String),
    /// Edit the bytes of a line.
    Bytes(Index, Vec<ByteEdit>),
}

/// Text values a parser of TOML or CSV trips on.
pub fn hostile_text() -> impl Strategy<Value = String> {
    prop_oneof![
        prop::sample::select(vec![
            "",
            "\"\"",
            "[]",
            "{}",
            "nan",
            "inf",
            "-inf",
            "-1",
            "0",
            "1e309",
            "1e-320",
            "18446744073709551616",
            "-9223372036854775809",
            "true",
            "\"x\"",
            "[1, \"a\"]",
            "{ a = 1 }",
            "\"\\u0000\"",
            "\"unterminated",
            "\"é\u{202e}\"",
            ",,,",
            "\"\"\"",
            "1,2,3",
            "none",
            "4294967296",
        ])
        .prop_map(str::to_owned),
        "[ -~]{0,12}",
    ]
}

/// A strategy of one line edit.
pub fn line_edit() -> impl Strategy<Value = LineEdit> {
    prop_oneof![
        2 => any::<Index>().prop_map(LineEdit::Remove),
        1 => any::<Index>().prop_map(LineEdit::Duplicate),
        1 => any::<Index>().prop_map(LineEdit::Swap),
        4 => (any::<Index>(), hostile_text()).prop_map(|(i, t)| LineEdit::Value(i, t)),
        1 => (any::<Index>(), hostile_text()).prop_map(|(i, t)| LineEdit::Insert(i, t)),
        1 => (any::<Index>(), byte_edits(3)).prop_map(|(i, e)| LineEdit::Bytes(i, e)),
    ]
}

/// A strategy of 1 to `max` line edits.
pub fn line_edits(max: usize) -> impl Strategy<Value = Vec<LineEdit>> {
    prop::collection::vec(line_edit(), 1..=max)
}

/// Applies line edits in order (the result may not be valid UTF-8 when bytes were
/// edited: lossily converted).
pub fn apply_lines(text: &str, edits: &[LineEdit]) -> String {
    let mut lines: Vec<String> = text.lines().map(str::to_owned).collect();
    for e in edits {
        if lines.is_empty() {
            lines.push(String::new());
        }
        let n = lines.len();
        match e {
            LineEdit::Remove(i) => {
                lines.remove(i.index(n));
            }
            LineEdit::Duplicate(i) => {
                let k = i.index(n);
                let l = lines[k].clone();
                lines.insert(k, l);
            }
            LineEdit::Swap(i) => {
                let k = i.index(n);
                if k + 1 < n {
                    lines.swap(k, k + 1);
                }
            }
            LineEdit::Value(i, t) => {
                let k = i.index(n);
                let l = &lines[k];
                lines[k] = match l.find(['=', ',']) {
                    Some(p) => format!("{} {t}", &l[..=p]),
                    None => t.clone(),
                };
            }
            LineEdit::Insert(i, t) => {
                lines.insert(i.index(n + 1), t.clone());
            }
            LineEdit::Bytes(i, edits) => {
                let k = i.index(n);
                lines[k] =
                    String::from_utf8_lossy(&apply_bytes(lines[k].as_bytes(), edits)).into_owned();
            }
        }
    }
    let mut out = lines.join("\n");
    out.push('\n');
    out
}
