//! Hostile MCAP teleop logs, made by mutating valid ones: bytes of the (compressed)
//! file, and records rewritten (message JSON, metadata, dropped, repeated or reordered
//! messages, times, topics) into an uncompressed file that is then byte-mutated too.
//! Read and validated as ingest does: no panic, no hang, and every rejection names the
//! file and the field.

use std::collections::BTreeMap;
use std::io::Cursor;
use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};

use dexjoco_core::{TaskSet, TaskSpec, synth};
use dexjoco_formats::EpisodeMeta;
use dexjoco_formats::mcap::write_episode_mcap;
use dexjoco_formats::{ReadOptions, Source, SourceKind};
use dexjoco_ingest::{ValidationOptions, validate};
use dexjoco_testkit::hostile::{
    ByteEdit, JsonEdit, apply_bytes, apply_json, byte_edits, hostile_text, json_edits, run_cases,
};
use mcap::records::{MessageHeader, Metadata, Record};
use proptest::prelude::*;
use proptest::sample::Index;

const FILE: &str = "hostile/teleop.mcap";

/// Valid logs: a one-arm and a two-arm episode, with and without `action_rotvec`.
fn bases() -> Vec<Vec<u8>> {
    let tmp = tempfile::tempdir().unwrap();
    let mut out = Vec::new();
    for (i, (task, frames)) in [
        ("click_mouse", 6),
        ("bimanual_hanoi", 4),
        ("pinch_tongs", 5),
    ]
    .into_iter()
    .enumerate()
    {
        let spec = TaskSpec::builtin(task).unwrap();
        let mut ep = synth::episode(spec, frames, i as u64);
        ep.id = format!("ep{i}");
        if i == 2 {
            ep.arrays.remove("action_rotvec");
        }
        let path = tmp.path().join(format!("{i}.mcap"));
        write_episode_mcap(&path, &ep, spec, &EpisodeMeta::default()).unwrap();
        out.push(fs_err::read(&path).unwrap());
    }
    out
}

/// A log's records: what the reader uses.
#[derive(Debug, Clone)]
struct Doc {
    metadata: Vec<(String, BTreeMap<String, String>)>,
    schemas: Vec<(u16, String, String, Vec<u8>)>,
    channels: Vec<(u16, u16, String, String)>,
    messages: Vec<(u16, u32, u64, Vec<u8>)>,
}

fn parse(bytes: &[u8]) -> Doc {
    let mut d = Doc {
        metadata: Vec::new(),
        schemas: Vec::new(),
        channels: Vec::new(),
        messages: Vec::new(),
    };
    for r in mcap::read::ChunkFlattener::new(bytes).unwrap() {
        match r.unwrap() {
            Record::Metadata(m) => d.metadata.push((m.name, m.metadata)),
            Record::Schema { header, data } => {
                d.schemas
                    .push((header.id, header.name, header.encoding, data.into_owned()));
            }
            Record::Channel(c) => {
                d.channels
                    .push((c.id, c.schema_id, c.topic, c.message_encoding));
            }
            Record::Message { header, data } => d.messages.push((
                header.channel_id,
                header.sequence,
                header.log_time,
                data.into_owned(),
            )),
            _ => {}
        }
    }
    d
}

/// Writes the records as an uncompressed log (`None` when the writer refuses them).
fn write(d: &Doc) -> Option<Vec<u8>> {
    let mut w = mcap::WriteOptions::new()
        .compression(None)
        .create(Cursor::new(Vec::new()))
        .ok()?;
    let mut schema_ids = BTreeMap::new();
    for (id, name, enc, data) in &d.schemas {
        schema_ids.insert(*id, w.add_schema(name, enc, data).ok()?);
    }
    let mut channel_ids = BTreeMap::new();
    for (id, schema, topic, enc) in &d.channels {
        let schema = schema_ids.get(schema).copied().unwrap_or(0);
        channel_ids.insert(
            *id,
            w.add_channel(schema, topic, enc, &BTreeMap::new()).ok()?,
        );
    }
    for (name, m) in &d.metadata {
        w.write_metadata(&Metadata {
            name: name.clone(),
            metadata: m.clone(),
        })
        .ok()?;
    }
    for (ch, seq, t, data) in &d.messages {
        if let Some(channel_id) = channel_ids.get(ch) {
            let header = MessageHeader {
                channel_id: *channel_id,
                sequence: *seq,
                log_time: *t,
                publish_time: *t,
            };
            w.write_to_known_channel(&header, data).ok()?;
        }
    }
    w.finish().ok()?;
    Some(w.into_inner().into_inner())
}

/// One change to a log's records.
#[derive(Debug, Clone)]
enum RecordEdit {
    MessageJson(Index, Vec<JsonEdit>),
    MessageBytes(Index, Vec<ByteEdit>),
    MetadataValue(Index, String),
    MetadataRemove(Index),
    Drop(Index),
    Repeat(Index),
    Swap(Index, Index),
    LogTime(Index, u64),
    Topic(Index, String),
}

fn record_edit() -> impl Strategy<Value = RecordEdit> {
    prop_oneof![
        6 => (any::<Index>(), json_edits(3)).prop_map(|(i, e)| RecordEdit::MessageJson(i, e)),
        1 => (any::<Index>(), byte_edits(2)).prop_map(|(i, e)| RecordEdit::MessageBytes(i, e)),
        3 => (any::<Index>(), hostile_text()).prop_map(|(i, t)| RecordEdit::MetadataValue(i, t)),
        1 => any::<Index>().prop_map(RecordEdit::MetadataRemove),
        1 => any::<Index>().prop_map(RecordEdit::Drop),
        1 => any::<Index>().prop_map(RecordEdit::Repeat),
        1 => (any::<Index>(), any::<Index>()).prop_map(|(a, b)| RecordEdit::Swap(a, b)),
        1 => (any::<Index>(), prop::sample::select(vec![0, 1, u64::MAX, 1 << 62]))
            .prop_map(|(i, t)| RecordEdit::LogTime(i, t)),
        1 => (any::<Index>(), prop::sample::select(vec![
                "/state".to_owned(), "/arm/pose_command".to_owned(), "/right/hand_target".to_owned(),
                "/action_rotvec".to_owned(), String::new(), "/left/pose_command".to_owned()]))
            .prop_map(|(i, t)| RecordEdit::Topic(i, t)),
    ]
}

fn apply_records(mut d: Doc, edits: &[RecordEdit]) -> Doc {
    for e in edits {
        let n = d.messages.len();
        match e {
            RecordEdit::MessageJson(i, j) if n > 0 => {
                let m = &mut d.messages[i.index(n)];
                if let Ok(v) = serde_json::from_slice::<serde_json::Value>(&m.3) {
                    m.3 = serde_json::to_vec(&apply_json(&v, j)).unwrap();
                }
            }
            RecordEdit::MessageBytes(i, b) if n > 0 => {
                let m = &mut d.messages[i.index(n)];
                m.3 = apply_bytes(&m.3, b);
            }
            RecordEdit::MetadataValue(i, t) => {
                if let Some((_, m)) = d.metadata.first_mut()
                    && !m.is_empty()
                {
                    let k = m.keys().nth(i.index(m.len())).unwrap().clone();
                    m.insert(k, t.clone());
                }
            }
            RecordEdit::MetadataRemove(i) => {
                if let Some((_, m)) = d.metadata.first_mut()
                    && !m.is_empty()
                {
                    let k = m.keys().nth(i.index(m.len())).unwrap().clone();
                    m.remove(&k);
                }
            }
            RecordEdit::Drop(i) if n > 0 => {
                d.messages.remove(i.index(n));
            }
            RecordEdit::Repeat(i) if n > 0 => {
                let k = i.index(n);
                let m = d.messages[k].clone();
                d.messages.insert(k, m);
            }
            RecordEdit::Swap(a, b) if n > 0 => d.messages.swap(a.index(n), b.index(n)),
            RecordEdit::LogTime(i, t) if n > 0 => d.messages[i.index(n)].2 = *t,
            RecordEdit::Topic(i, t) if !d.channels.is_empty() => {
                let k = i.index(d.channels.len());
                d.channels[k].2 = t.clone();
            }
            _ => {}
        }
    }
    d
}

/// Cases read whole (then validated) and rejected by the reader.
static READ: AtomicUsize = AtomicUsize::new(0);
static REJECTED: AtomicUsize = AtomicUsize::new(0);

/// Reads and validates as ingest does; a rejection must name the file and the field.
fn check(bytes: &[u8]) -> Result<(), String> {
    let path = Path::new(FILE);
    let source = Source {
        path: path.to_owned(),
        kind: SourceKind::Mcap,
    };
    let tasks = TaskSet::builtin();
    let read = source.read_with(
        tasks,
        ReadOptions {
            task: None,
            bytes: Some(bytes),
        },
    );
    match read {
        Err(e) => {
            REJECTED.fetch_add(1, Ordering::Relaxed);
            let msg = e.to_string();
            if !msg.contains(&format!("file '{FILE}'")) || !msg.contains("field '") {
                return Err(format!("a rejection without file and field: {msg}"));
            }
        }
        Ok(r) => {
            READ.fetch_add(1, Ordering::Relaxed);
            let task = tasks
                .get(&r.episode.task)
                .ok_or("an unknown task was read")?;
            for p in validate(&r.episode, task, path, &ValidationOptions::default()) {
                if p.file.as_deref() != Some(path) || p.field.is_none() {
                    return Err(format!("a problem without file and field: {p:?}"));
                }
            }
        }
    }
    Ok(())
}

#[test]
fn mutated_bytes_of_valid_logs_are_rejected_by_name_never_a_panic() {
    let bases = bases();
    let strategy = (0..bases.len(), byte_edits(4));
    let took = run_cases("mcap bytes", 1500, strategy, move |(b, edits)| {
        check(&apply_bytes(&bases[b], &edits))
    });
    assert!(took.as_secs() < 120, "{took:?}");
    assert!(
        REJECTED.load(Ordering::Relaxed) > 100,
        "the mutations reach the reader"
    );
}

#[test]
fn mutated_records_of_valid_logs_are_rejected_by_name_never_a_panic() {
    let docs: Vec<Doc> = bases().iter().map(|b| parse(b)).collect();
    // The rewriting itself keeps a valid log valid.
    for d in &docs {
        let file = write(d).unwrap();
        let r = Source {
            path: FILE.into(),
            kind: SourceKind::Mcap,
        }
        .read_with(
            TaskSet::builtin(),
            ReadOptions {
                task: None,
                bytes: Some(&file),
            },
        );
        assert!(r.is_ok(), "{r:?}");
    }
    let strategy = (
        0..docs.len(),
        prop::collection::vec(record_edit(), 1..4),
        prop::option::weighted(0.3, byte_edits(2)),
    );
    let took = run_cases("mcap records", 1500, strategy, move |(b, edits, bytes)| {
        let doc = apply_records(docs[b].clone(), &edits);
        let Some(file) = write(&doc) else {
            return Ok(());
        };
        let file = match &bytes {
            Some(e) => apply_bytes(&file, e),
            None => file,
        };
        check(&file)
    });
    assert!(took.as_secs() < 120, "{took:?}");
    // Both ways out are taken: the edits reach past the container into the values.
    assert!(
        READ.load(Ordering::Relaxed) > 100,
        "some mutated logs read whole"
    );
    assert!(REJECTED.load(Ordering::Relaxed) > 100, "some are rejected");
}
