//! Writing an episode as an MCAP teleop log: the episode record, one channel per stream,
//! one message per frame.

use super::*;

fn stamp(t: f64) -> Value {
    let t = if t.is_finite() && t > 0.0 { t } else { 0.0 };
    let sec = t.floor();
    let nsec = (((t - sec) * 1e9).round() as u64).min(999_999_999);
    json!({"sec": sec as u64, "nsec": nsec})
}

fn log_time(t: f64) -> u64 {
    if t.is_finite() && t > 0.0 {
        (t * 1e9).round() as u64
    } else {
        0
    }
}

/// Writes an episode as one MCAP file (atomically: a temporary file renamed into place).
pub fn write_episode_mcap(
    path: &Path,
    ep: &Episode,
    task: &TaskSpec,
    meta: &EpisodeMeta,
) -> Result<()> {
    let tmp = crate::fs::temp_file_beside(path)?;
    let at = Location::episode(&ep.id).path(path);
    let mcap_err = |source| FormatError::Mcap {
        at: at.clone(),
        source: Box::new(source),
    };
    {
        let file = tmp
            .as_file()
            .try_clone()
            .map_err(io_err("open", tmp.path()))?;
        let mut w = mcap::WriteOptions::new()
            .library(concat!("dexjoco-data/", env!("CARGO_PKG_VERSION")))
            .create(BufWriter::new(file))
            .map_err(mcap_err)?;
        write_into(&mut w, ep, task, meta).map_err(mcap_err)?;
        w.finish().map_err(mcap_err)?;
        let mut inner = w.into_inner();
        inner.flush().map_err(io_err("write", tmp.path()))?;
    }
    crate::fs::persist_synced(tmp, path)
}

fn write_into<W: std::io::Write + std::io::Seek>(
    w: &mut mcap::Writer<W>,
    ep: &Episode,
    task: &TaskSpec,
    meta: &EpisodeMeta,
) -> mcap::McapResult<()> {
    w.write_metadata(&Metadata {
        name: EPISODE_METADATA.to_owned(),
        metadata: episode_record(ep, task.setup, meta),
    })?;
    let channels = add_channels(w, task, ep.array(Episode::ACTION_ROTVEC).is_some())?;
    write_frames(w, ep, task.setup, &channels)
}

/// The `dexjoco.episode` record: the episode's task, prompt, fps and setup, its id when
/// it has one, then `meta` (its other keys never replace these).
fn episode_record(ep: &Episode, setup: ArmSetup, meta: &EpisodeMeta) -> BTreeMap<String, String> {
    let mut md = BTreeMap::new();
    md.insert("schema_version".to_owned(), SCHEMA_VERSION.to_owned());
    md.insert("task".to_owned(), ep.task.clone());
    md.insert("prompt".to_owned(), ep.prompt.clone());
    md.insert("fps".to_owned(), ep.fps.to_string());
    md.insert(
        "setup".to_owned(),
        match setup {
            ArmSetup::SingleArm => "single_arm",
            ArmSetup::Bimanual => "bimanual",
        }
        .to_owned(),
    );
    if !ep.id.is_empty() {
        md.insert("episode_id".to_owned(), ep.id.clone());
    }
    for (k, v) in [
        ("operator", &meta.operator),
        ("date", &meta.date),
        ("source", &meta.source),
    ] {
        if let Some(v) = v {
            md.insert(k.to_owned(), v.clone());
        }
    }
    for (k, v) in &meta.extra {
        md.entry(k.clone()).or_insert_with(|| v.clone());
    }
    md
}

/// The channel ids of one file.
struct Channels {
    /// Per arm: its pose command and hand target channels.
    arms: Vec<(u16, u16)>,
    state: u16,
    rotvec: Option<u16>,
}

/// Adds the schemas and channels (the rotation-vector one when `rotvec`).
fn add_channels<W: std::io::Write + std::io::Seek>(
    w: &mut mcap::Writer<W>,
    task: &TaskSpec,
    rotvec: bool,
) -> mcap::McapResult<Channels> {
    let pose_schema = w.add_schema("foxglove.PoseInFrame", "jsonschema", POSE_SCHEMA.as_bytes())?;
    let hand_schema = w.add_schema(
        "dexjoco.HandJointTargets",
        "jsonschema",
        HAND_SCHEMA.as_bytes(),
    )?;
    let state_schema = w.add_schema("dexjoco.State", "jsonschema", STATE_SCHEMA.as_bytes())?;
    let mut arms = Vec::new();
    for arm in task.setup.arm_names() {
        let pose = w.add_channel(pose_schema, &pose_topic(arm), "json", &BTreeMap::new())?;
        let mut hm = BTreeMap::new();
        hm.insert("joint_order".to_owned(), joint_order(arm));
        let hand = w.add_channel(hand_schema, &hand_topic(arm), "json", &hm)?;
        arms.push((pose, hand));
    }
    let mut sm = BTreeMap::new();
    let layout = task.state_layout();
    sm.insert(
        "layout".to_owned(),
        (0..task.state.width)
            .map(|c| layout.column_name(c))
            .collect::<Vec<_>>()
            .join(","),
    );
    let state = w.add_channel(state_schema, STATE_TOPIC, "json", &sm)?;
    let rotvec = if rotvec {
        let s = w.add_schema(
            "dexjoco.ActionRotvec",
            "jsonschema",
            ROTVEC_SCHEMA.as_bytes(),
        )?;
        Some(w.add_channel(s, ACTION_ROTVEC_TOPIC, "json", &BTreeMap::new())?)
    } else {
        None
    };
    Ok(Channels {
        arms,
        state,
        rotvec,
    })
}

/// One message per channel and frame, frame by frame.
fn write_frames<W: std::io::Write + std::io::Seek>(
    w: &mut mcap::Writer<W>,
    ep: &Episode,
    setup: ArmSetup,
    channels: &Channels,
) -> mcap::McapResult<()> {
    let action = ep.array(Episode::ACTION);
    let state = ep.array(Episode::STATE);
    let rotvec = ep.array(Episode::ACTION_ROTVEC);
    let ts = ep.array(Episode::TIMESTAMP);
    let per_arm = setup.action_dim() / setup.arms();
    let put = |w: &mut mcap::Writer<W>, ch: u16, k: usize, t: f64, v: &Value| {
        let data = serde_json::to_vec(v).expect("JSON values serialize");
        w.write_to_known_channel(
            &MessageHeader {
                channel_id: ch,
                sequence: k as u32,
                log_time: log_time(t),
                publish_time: log_time(t),
            },
            &data,
        )
    };
    for k in 0..ep.len() {
        let t = ts.map_or(k as f64 / ep.fps, |a| a.row(k)[0]);
        if let Some(action) = action {
            let row = action.row(k);
            for (arm, (pose_ch, hand_ch)) in channels.arms.iter().enumerate() {
                let a = &row[arm * per_arm..(arm + 1) * per_arm];
                let pose = json!({
                    "timestamp": stamp(t),
                    "frame_id": "world",
                    "pose": {
                        "position": {"x": a[0], "y": a[1], "z": a[2]},
                        "orientation": {"x": a[4], "y": a[5], "z": a[6], "w": a[3]},
                    }
                });
                put(w, *pose_ch, k, t, &pose)?;
                let hand = json!({"timestamp": stamp(t), "frame": k, "position": &a[7..]});
                put(w, *hand_ch, k, t, &hand)?;
            }
        }
        if let Some(state) = state {
            let msg = json!({"timestamp": stamp(t), "frame": k, "time": t, "values": state.row(k)});
            put(w, channels.state, k, t, &msg)?;
        }
        if let (Some(rv), Some(ch)) = (rotvec, channels.rotvec) {
            let msg = json!({"timestamp": stamp(t), "frame": k, "values": rv.row(k)});
            put(w, ch, k, t, &msg)?;
        }
    }
    Ok(())
}
