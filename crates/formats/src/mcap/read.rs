//! Reading an MCAP teleop log back into an episode: the file checked record by record,
//! messages grouped by topic, every stream checked against the task's layout.

use super::*;

/// A topic's schema name and messages.
type TopicMessages = (Option<String>, Vec<Msg>);

struct Msg {
    log_time: u64,
    sequence: u32,
    order: usize,
    data: Vec<u8>,
}

fn mcap_problem(e: &mcap::McapError, at: &Location) -> FormatError {
    use mcap::McapError as E;
    let code = match e {
        E::UnexpectedEof | E::UnexpectedEoc | E::BadFooter => ProblemCode::Truncated,
        E::Io(io) if io.kind() == std::io::ErrorKind::UnexpectedEof => ProblemCode::Truncated,
        _ => ProblemCode::Corrupt,
    };
    let detail = match code {
        ProblemCode::Truncated => format!("the MCAP file ends early ({e})"),
        _ => format!("damaged MCAP file ({e})"),
    };
    FormatError::input(code, at, detail)
}

/// The records of an MCAP file, chunks unpacked, chunk CRCs checked, and no record
/// longer than the file could hold (so a damaged length field cannot make the reader
/// allocate without bound).
fn flat_records(bytes: &[u8]) -> impl Iterator<Item = mcap::McapResult<Record<'static>>> + '_ {
    use mcap::sans_io::{LinearReadEvent, LinearReader, LinearReaderOptions};
    // A record inside a chunk is at most its uncompressed chunk: bounded by the file's
    // size times a compression ratio no JSON teleop log reaches.
    let limit = bytes.len().saturating_mul(64).max(16 << 20);
    let mut reader = LinearReader::new_with_options(
        LinearReaderOptions::default()
            .with_record_length_limit(limit)
            .with_validate_chunk_crcs(true),
    );
    let mut rest = bytes;
    std::iter::from_fn(move || {
        while let Some(event) = reader.next_event() {
            match event {
                Ok(LinearReadEvent::ReadRequest(need)) => {
                    let len = need.min(rest.len());
                    reader.insert(len).copy_from_slice(&rest[..len]);
                    reader.notify_read(len);
                    rest = &rest[len..];
                }
                Ok(LinearReadEvent::Record { data, opcode }) => {
                    return Some(mcap::parse_record(opcode, data).map(Record::into_owned));
                }
                Err(e) => return Some(Err(e)),
            }
        }
        None
    })
    .fuse()
}

/// Reads an MCAP file's bytes (`path` only names it in problems); the episode's task
/// must be one of `tasks`.
pub fn read_episode_mcap(path: &Path, bytes: &[u8], tasks: &TaskSet) -> Result<TeleopEpisode> {
    let base = Location::default().path(path);
    // Whole-file problems name the part of the file: its magic, or its records.
    check_magic(bytes, &base.clone().field("magic"))?;
    let file = collect_records(bytes, &base.clone().field("records"))?;
    let md_at = base.clone().field(format!("metadata '{EPISODE_METADATA}'"));
    let FileRecords {
        metadata,
        schemas,
        channels,
        by_channel,
    } = file;
    let md = metadata.ok_or_else(|| {
        FormatError::input(
            ProblemCode::MissingArray,
            &md_at,
            "no episode metadata record (task, fps, setup)",
        )
    })?;
    let (task, fps) = episode_header(&md, &md_at, tasks)?;
    let topics = Topics {
        base: &base,
        topics: messages_by_topic(by_channel, &channels, &schemas, &base)?,
    };

    let (state_rows, times) = topics.read_state(task)?;
    let frames = state_rows.len();
    let action = topics.read_actions(task, frames)?;
    let mut arrays = BTreeMap::new();
    arrays.insert(
        Episode::ACTION.to_owned(),
        FrameArray::new(task.setup.action_dim(), action)?,
    );
    arrays.insert(
        Episode::STATE.to_owned(),
        FrameArray::from_rows(&state_rows)?,
    );
    arrays.insert(Episode::TIMESTAMP.to_owned(), FrameArray::new(1, times)?);
    if let Some(rotvec) = topics.read_rotvec(task, frames)? {
        arrays.insert(Episode::ACTION_ROTVEC.to_owned(), rotvec);
    }
    let mut notes = topics.unused_topic_notes(task);

    let get = |k: &str| md.get(k).map(String::as_str);
    let id = get("episode_id").unwrap_or_default();
    if !id.is_empty() {
        // The id names the episode's folders and files later on: a name, not a path.
        dexjoco_core::safe_name("episode id", id).map_err(|e| {
            FormatError::input(
                ProblemCode::UnsafeName,
                &md_at.clone().field("episode_id"),
                e.to_string(),
            )
        })?;
    }
    let mut episode = Episode {
        id: id.to_owned(),
        task: task.id.clone(),
        // An empty prompt is no instruction of its own: the task's applies.
        prompt: get("prompt")
            .filter(|p| !p.trim().is_empty())
            .unwrap_or(&task.prompt)
            .to_owned(),
        fps,
        arrays,
        cameras: Vec::new(),
    };
    if episode.array(Episode::ACTION_ROTVEC).is_none() && frames > 0 {
        episode.compute_action_rotvec(task.setup)?;
        notes.push("action_rotvec was absent: computed from the pose commands".into());
    }
    Ok(TeleopEpisode {
        episode,
        meta: episode_meta(&md),
        notes,
    })
}

/// A problem unless `bytes` start with the MCAP magic.
fn check_magic(bytes: &[u8], magic: &Location) -> Result<()> {
    if bytes.is_empty() {
        return Err(FormatError::input(
            ProblemCode::EmptyFile,
            magic,
            "the file is empty",
        ));
    }
    if !bytes.starts_with(mcap::MAGIC) {
        return Err(FormatError::input(
            ProblemCode::Corrupt,
            magic,
            "not an MCAP file (no MCAP magic at the start)",
        ));
    }
    Ok(())
}

/// The records of a file an episode is made of.
#[derive(Default)]
struct FileRecords {
    /// The `dexjoco.episode` record's keys.
    metadata: Option<BTreeMap<String, String>>,
    /// Schema names by id.
    schemas: HashMap<u16, String>,
    /// Topic and schema id by channel id.
    channels: HashMap<u16, (String, u16)>,
    /// Messages by channel id, in file order.
    by_channel: HashMap<u16, Vec<Msg>>,
}

/// Reads every record of the file (problems name `records`).
fn collect_records(bytes: &[u8], records: &Location) -> Result<FileRecords> {
    let mut file = FileRecords::default();
    let mut order = 0usize;
    for rec in flat_records(bytes) {
        match rec.map_err(|e| mcap_problem(&e, records))? {
            Record::Metadata(m) if m.name == EPISODE_METADATA => file.metadata = Some(m.metadata),
            Record::Schema { header, .. } => {
                file.schemas.insert(header.id, header.name);
            }
            Record::Channel(c) => {
                file.channels.insert(c.id, (c.topic, c.schema_id));
            }
            Record::Message { header, data } => {
                file.by_channel
                    .entry(header.channel_id)
                    .or_default()
                    .push(Msg {
                        log_time: header.log_time,
                        sequence: header.sequence,
                        order,
                        data: data.into_owned(),
                    });
                order += 1;
            }
            _ => {}
        }
    }
    Ok(file)
}

/// The task (one of `tasks`, of the recorded setup) and fps the metadata record names.
fn episode_header<'t>(
    md: &BTreeMap<String, String>,
    md_at: &Location,
    tasks: &'t TaskSet,
) -> Result<(&'t TaskSpec, f64)> {
    let get = |k: &str| md.get(k).map(String::as_str);
    if let Some(v) = get("schema_version").filter(|v| *v != SCHEMA_VERSION) {
        return Err(FormatError::input(
            ProblemCode::Corrupt,
            md_at,
            format!("schema_version {v} is not {SCHEMA_VERSION}"),
        ));
    }
    let task_id = get("task").unwrap_or_default();
    let task = tasks
        .get(task_id)
        .ok_or_else(|| unknown_task(&md_at.clone().field("task"), task_id, tasks))?;
    if let Some(setup) = get("setup") {
        let expected = match task.setup {
            ArmSetup::SingleArm => "single_arm",
            ArmSetup::Bimanual => "bimanual",
        };
        if setup != expected {
            return Err(FormatError::input(
                ProblemCode::WrongDimensions,
                &md_at.clone().field("setup"),
                format!("setup '{setup}' but task {} is {expected}", task.id),
            ));
        }
    }
    let fps = match get("fps") {
        None => dexjoco_core::DEXJOCO_FPS,
        Some(s) => s.parse::<f64>().map_err(|_| {
            FormatError::input(
                ProblemCode::Corrupt,
                &md_at.clone().field("fps"),
                format!("fps '{s}' is not a number"),
            )
        })?,
    };
    Ok((task, fps))
}

/// Messages per topic, in time order (file order breaks ties).
fn messages_by_topic(
    by_channel: HashMap<u16, Vec<Msg>>,
    channels: &HashMap<u16, (String, u16)>,
    schemas: &HashMap<u16, String>,
    base: &Location,
) -> Result<HashMap<String, TopicMessages>> {
    let mut topics: HashMap<String, TopicMessages> = HashMap::new();
    for (ch, mut msgs) in by_channel {
        let (topic, schema_id) = channels.get(&ch).cloned().ok_or_else(|| {
            FormatError::input(
                ProblemCode::Corrupt,
                &base.clone().field(format!("channel {ch}")),
                format!("messages on channel {ch}, which has no channel record"),
            )
        })?;
        msgs.sort_by_key(|m| (m.log_time, m.sequence, m.order));
        let schema = schemas.get(&schema_id).cloned();
        topics
            .entry(topic)
            .or_insert((schema, Vec::new()))
            .1
            .extend(msgs);
    }
    Ok(topics)
}

/// A file's messages by topic; problems name the file (`base`), topic and frame.
struct Topics<'a> {
    base: &'a Location,
    topics: HashMap<String, TopicMessages>,
}

impl Topics<'_> {
    fn corrupt(&self, topic: &str, k: usize, message: String) -> FormatError {
        FormatError::input(
            ProblemCode::Corrupt,
            &self.base.clone().field(topic).frame(k),
            message,
        )
    }

    fn parse(&self, topic: &str, k: usize, m: &Msg) -> Result<Value> {
        serde_json::from_slice(&m.data)
            .map_err(|e| self.corrupt(topic, k, format!("message is not valid JSON: {e}")))
    }

    fn num(&self, v: &Value, topic: &str, k: usize, what: &str) -> Result<f64> {
        v.as_f64()
            .ok_or_else(|| self.corrupt(topic, k, format!("{what} is not a number")))
    }

    fn numbers(&self, v: Option<&Value>, topic: &str, k: usize, what: &str) -> Result<Vec<f64>> {
        let arr = v.and_then(Value::as_array).ok_or_else(|| {
            self.corrupt(topic, k, format!("`{what}` is not an array of numbers"))
        })?;
        arr.iter().map(|x| self.num(x, topic, k, what)).collect()
    }

    /// A problem when message `k` says it is another frame.
    fn frame_check(&self, v: &Value, topic: &str, k: usize) -> Result<()> {
        match v.get("frame").and_then(Value::as_u64) {
            Some(f) if f as usize == k => Ok(()),
            Some(f) => Err(FormatError::input(
                ProblemCode::WrongLength,
                &self.base.clone().field(topic).frame(k),
                format!("message {k} says frame {f}: a frame is missing or repeated"),
            )),
            None => Ok(()),
        }
    }

    fn required(&self, topic: &str) -> Result<&Vec<Msg>> {
        self.topics.get(topic).map(|(_, m)| m).ok_or_else(|| {
            FormatError::input(
                ProblemCode::MissingArray,
                &self.base.clone().field(topic),
                "required channel is missing",
            )
        })
    }

    /// The state rows and the exact timestamps (`time`, else the log time).
    fn read_state(&self, task: &TaskSpec) -> Result<(Vec<Vec<f64>>, Vec<f64>)> {
        let state_msgs = self.required(STATE_TOPIC)?;
        let frames = state_msgs.len();
        let mut state_rows = Vec::with_capacity(frames);
        let mut times = Vec::with_capacity(frames);
        for (k, m) in state_msgs.iter().enumerate() {
            let v = self.parse(STATE_TOPIC, k, m)?;
            self.frame_check(&v, STATE_TOPIC, k)?;
            let row = self.numbers(v.get("values"), STATE_TOPIC, k, "values")?;
            if row.len() != task.state.width {
                return Err(FormatError::input(
                    ProblemCode::WrongDimensions,
                    &self.base.clone().field(STATE_TOPIC).frame(k),
                    format!(
                        "{} state values where {} has {}",
                        row.len(),
                        task.id,
                        task.state.width
                    ),
                ));
            }
            state_rows.push(row);
            times.push(match v.get("time") {
                Some(t) => self.num(t, STATE_TOPIC, k, "time")?,
                None => m.log_time as f64 * 1e-9,
            });
        }
        Ok((state_rows, times))
    }

    /// The actions of `frames` frames from the per-arm pose commands and hand targets.
    fn read_actions(&self, task: &TaskSpec, frames: usize) -> Result<Vec<f64>> {
        let per_arm = task.setup.action_dim() / task.setup.arms();
        let mut action = vec![0.0; frames * task.setup.action_dim()];
        for (arm_i, arm) in task.setup.arm_names().iter().enumerate() {
            for (topic, is_pose) in [(pose_topic(arm), true), (hand_topic(arm), false)] {
                let msgs = self.required(&topic)?;
                if msgs.len() != frames {
                    return Err(FormatError::input(
                        ProblemCode::WrongLength,
                        &self.base.clone().field(topic.as_str()),
                        format!("{} messages where {STATE_TOPIC} has {frames}", msgs.len()),
                    ));
                }
                for (k, m) in msgs.iter().enumerate() {
                    let v = self.parse(&topic, k, m)?;
                    let out =
                        &mut action[k * per_arm * task.setup.arms() + arm_i * per_arm..][..per_arm];
                    if is_pose {
                        self.pose_into(&v, &topic, k, out)?;
                    } else {
                        self.hand_into(&v, &topic, k, out)?;
                    }
                }
            }
        }
        Ok(action)
    }

    /// A pose command into an arm's action: position, then quaternion w, x, y, z.
    fn pose_into(&self, v: &Value, topic: &str, k: usize, out: &mut [f64]) -> Result<()> {
        let pose = v.get("pose").unwrap_or(&Value::Null);
        let p = pose.get("position").unwrap_or(&Value::Null);
        let q = pose.get("orientation").unwrap_or(&Value::Null);
        let field = |o: &Value, key: &str| -> Result<f64> {
            self.num(
                o.get(key).unwrap_or(&Value::Null),
                topic,
                k,
                &format!("pose.{key}"),
            )
        };
        out[0] = field(p, "x")?;
        out[1] = field(p, "y")?;
        out[2] = field(p, "z")?;
        out[3] = field(q, "w")?;
        out[4] = field(q, "x")?;
        out[5] = field(q, "y")?;
        out[6] = field(q, "z")?;
        Ok(())
    }

    /// Hand joint targets into the rest of an arm's action.
    fn hand_into(&self, v: &Value, topic: &str, k: usize, out: &mut [f64]) -> Result<()> {
        self.frame_check(v, topic, k)?;
        let hand = self.numbers(v.get("position"), topic, k, "position")?;
        if hand.len() != HAND_DOF {
            return Err(FormatError::input(
                ProblemCode::WrongDimensions,
                &self.base.clone().field(topic).frame(k),
                format!(
                    "{} hand targets where the Allegro hand has {HAND_DOF}",
                    hand.len()
                ),
            ));
        }
        out[7..].copy_from_slice(&hand);
        Ok(())
    }

    /// The recorded rotation-vector actions, when the file has them (and frames).
    fn read_rotvec(&self, task: &TaskSpec, frames: usize) -> Result<Option<FrameArray>> {
        let Some((_, msgs)) = self.topics.get(ACTION_ROTVEC_TOPIC) else {
            return Ok(None);
        };
        let mut rows = Vec::with_capacity(msgs.len());
        for (k, m) in msgs.iter().enumerate() {
            let v = self.parse(ACTION_ROTVEC_TOPIC, k, m)?;
            self.frame_check(&v, ACTION_ROTVEC_TOPIC, k)?;
            rows.push(self.numbers(v.get("values"), ACTION_ROTVEC_TOPIC, k, "values")?);
        }
        if rows.len() != frames {
            return Err(FormatError::input(
                ProblemCode::WrongLength,
                &self.base.clone().field(ACTION_ROTVEC_TOPIC),
                format!("{} messages where {STATE_TOPIC} has {frames}", rows.len()),
            ));
        }
        if rows
            .iter()
            .any(|r| r.len() != task.setup.action_rotvec_dim())
        {
            return Err(FormatError::input(
                ProblemCode::WrongDimensions,
                &self.base.clone().field(ACTION_ROTVEC_TOPIC),
                format!(
                    "rows are not {} values wide",
                    task.setup.action_rotvec_dim()
                ),
            ));
        }
        Ok(if frames > 0 {
            Some(FrameArray::from_rows(&rows)?)
        } else {
            None
        })
    }

    /// Streams the raw layout has no place for are named, never dropped silently.
    fn unused_topic_notes(&self, task: &TaskSpec) -> Vec<String> {
        let mut other: Vec<(&String, &TopicMessages)> = self
            .topics
            .iter()
            .filter(|(t, _)| {
                *t != STATE_TOPIC
                    && *t != ACTION_ROTVEC_TOPIC
                    && !task
                        .setup
                        .arm_names()
                        .iter()
                        .any(|a| **t == pose_topic(a) || **t == hand_topic(a))
            })
            .collect();
        other.sort_by_key(|(t, _)| t.as_str());
        other
            .into_iter()
            .map(|(topic, (schema, msgs))| {
                format!(
                    "{} messages on '{topic}' ({}) are not part of the raw layout: kept only in the source file",
                    msgs.len(),
                    schema.as_deref().unwrap_or("no schema")
                )
            })
            .collect()
    }
}

/// The metadata record's keys beyond those the episode is made of.
fn episode_meta(md: &BTreeMap<String, String>) -> EpisodeMeta {
    let known = [
        "schema_version",
        "task",
        "prompt",
        "fps",
        "setup",
        "episode_id",
        "operator",
        "date",
        "source",
    ];
    let get = |k: &str| md.get(k).cloned();
    EpisodeMeta {
        operator: get("operator"),
        date: get("date"),
        source: get("source"),
        extra: md
            .iter()
            .filter(|(k, _)| !known.contains(&k.as_str()))
            .map(|(k, v)| (k.clone(), v.clone()))
            .collect(),
    }
}
