//! Re-encoding: frames decoded from ranges of videos as yuv420p (no colour conversion on
//! the way) and piped into one [`VideoWriter`] with a new codec, quality and keyframes.

use std::io::Read;
use std::path::Path;
use std::process::{Command, Stdio};

use crate::{
    ConcatInput, Keyframes, VideoError, VideoSpec, VideoWriter, ffmpeg_program, probe, spawn_ffmpeg,
};

/// Decodes the frames of `inputs` in order (each from frame `skip`, `take` frames or to
/// its end) and encodes them as one video `out` with `spec`'s codec and `keyframes`
/// (positions counted in the output). Returns the frames written. Inputs must have
/// `spec`'s size; the output is written atomically, as every [`VideoWriter`]'s.
pub fn transcode(
    inputs: &[ConcatInput],
    out: &Path,
    spec: VideoSpec,
    keyframes: &Keyframes,
) -> Result<usize, VideoError> {
    let mut writer = VideoWriter::create_yuv420p(out, spec, keyframes)?;
    let mut frame = vec![0u8; spec.width as usize * spec.height as usize * 3 / 2];
    for input in inputs {
        let info = probe(&input.path)?;
        if (info.width, info.height) != (spec.width, spec.height) {
            return Err(VideoError::Failed {
                program: "transcode".into(),
                path: input.path.clone(),
                message: format!(
                    "{}x{} frames, but the output is {}x{}",
                    info.width, info.height, spec.width, spec.height
                ),
            });
        }
        let decoded = decode_range(input, spec.fps, &mut frame, &mut |f| writer.write_frame(f))?;
        if input.take.is_some_and(|t| t != decoded) {
            return Err(VideoError::Failed {
                program: "transcode".into(),
                path: input.path.clone(),
                message: format!(
                    "{decoded} frames decoded from frame {}, {} asked for",
                    input.skip,
                    input.take.unwrap_or(0)
                ),
            });
        }
    }
    writer.finish()
}

/// Decodes `input`'s frames as yuv420p into `frame`, one at a time, handing each to
/// `sink`; returns how many there were.
fn decode_range(
    input: &ConcatInput,
    fps: u32,
    frame: &mut [u8],
    sink: &mut dyn FnMut(&[u8]) -> Result<(), VideoError>,
) -> Result<usize, VideoError> {
    let mut cmd = Command::new(ffmpeg_program());
    cmd.args(["-v", "error", "-nostdin"]);
    if input.skip > 0 {
        // Half a frame before frame `skip`: the decoder starts at the keyframe before
        // it and drops every frame presented before this time, so `skip` comes first.
        let at = (input.skip as f64 - 0.5) / f64::from(fps.max(1));
        cmd.args(["-ss", &format!("{at:.6}")]);
    }
    cmd.arg("-i").arg(&input.path);
    if let Some(take) = input.take {
        cmd.args(["-frames:v", &take.to_string()]);
    }
    cmd.args(["-map", "0:v:0", "-fps_mode", "passthrough"])
        .args(["-f", "rawvideo", "-pix_fmt", "yuv420p", "-"])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    let mut child = spawn_ffmpeg(&mut cmd, &input.path)?;
    let mut stdout = child.stdout.take().expect("piped stdout");
    let io = |source| VideoError::Io {
        path: input.path.clone(),
        source,
    };
    let mut frames = 0;
    loop {
        let filled = fill(&mut stdout, frame).map_err(io)?;
        if filled == frame.len() {
            sink(frame)?;
            frames += 1;
            continue;
        }
        drop(stdout);
        let out = child.wait_with_output().map_err(io)?;
        if !out.status.success() || filled != 0 {
            return Err(VideoError::Failed {
                program: "ffmpeg".into(),
                path: input.path.clone(),
                message: format!(
                    "decoding stopped after {frames} frames ({}): {}",
                    out.status,
                    String::from_utf8_lossy(&out.stderr).trim()
                ),
            });
        }
        return Ok(frames);
    }
}

/// Reads into `buf` until it is full or the stream ends; the bytes read.
fn fill(reader: &mut impl Read, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut filled = 0;
    while filled < buf.len() {
        match reader.read(&mut buf[filled..]) {
            Ok(0) => break,
            Ok(n) => filled += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(filled)
}

/// Encoder settings to try for the frames a smart cut re-encodes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Encoding {
    /// Codec and quality.
    pub codec: crate::Codec,
    /// Keyframe interval (`-g`); H.264's headers depend on it.
    pub interval: Option<u32>,
}

/// Where a video's stream can be cut without re-encoding, by frame (presentation order):
/// a copy can start at a keyframe that no earlier-decoded frame is presented after, and
/// end before a frame where every packet decoded before it is presented before it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CutPoints {
    start: Vec<bool>,
    end: Vec<bool>,
}

impl CutPoints {
    /// The cut points of `path`, from its packets.
    pub fn of(path: &Path) -> Result<Self, VideoError> {
        let packets = crate::packets_in_decoding_order(path)?;
        let n = packets.len();
        let mut times: Vec<f64> = packets.iter().map(|p| p.pts).collect();
        times.sort_by(f64::total_cmp);
        let frame = |pts: f64| times.partition_point(|t| *t < pts);
        // Largest time decoded before each packet, smallest decoded from it on.
        let mut before = vec![f64::NEG_INFINITY; n + 1];
        for p in 1..=n {
            before[p] = before[p - 1].max(packets[p - 1].pts);
        }
        let mut from = vec![f64::INFINITY; n + 1];
        for p in (0..n).rev() {
            from[p] = from[p + 1].min(packets[p].pts);
        }
        // A copy ends before frame f where the first f packets decoded are the first f
        // frames; it starts at a keyframe decoded after every earlier frame and before
        // every later one.
        let end = (0..=n).map(|f| f == n || before[f] < times[f]).collect();
        let mut start = vec![false; n + 1];
        for (p, packet) in packets.iter().enumerate() {
            let closed = before[p] < packet.pts && from[p] >= packet.pts;
            start[frame(packet.pts)] = closed && packet.key;
        }
        Ok(Self { start, end })
    }

    /// Frames in the video.
    pub fn frames(&self) -> usize {
        self.start.len() - 1
    }

    /// Whether a stream copy can start at frame `f`.
    pub fn can_start(&self, f: usize) -> bool {
        self.start.get(f).copied().unwrap_or(false)
    }

    /// Whether a stream copy can end just before frame `f` (`frames()`: at the end).
    pub fn can_end(&self, f: usize) -> bool {
        self.end.get(f).copied().unwrap_or(false)
    }
}

/// A smart cut made by [`smart_cut`].
#[derive(Debug, Clone, PartialEq)]
pub struct SmartCut {
    /// The inputs for [`crate::concat_copy`]: re-encoded frames up to the first frame a
    /// stream copy can start at, the source by stream copy, re-encoded frames after the
    /// last point the copy can end at.
    pub inputs: Vec<ConcatInput>,
    /// Which of the candidates encoded the re-encoded frames (none when none were).
    pub candidate: Option<usize>,
    /// Frames re-encoded.
    pub reencoded: usize,
}

/// Frames `skip .. skip + take` of `src` (whose cut points are `cuts`) as inputs for
/// [`crate::concat_copy`], almost all by stream copy: only the frames before the first
/// point a copy can start at and after the last point it can end at are decoded and
/// re-encoded into files under `scratch`. Those must join the source's stream, so they
/// are encoded with the first of `candidates` whose out-of-band parameters (H.264's
/// SPS/PPS, AV1's sequence header) equal the source's, byte for byte; `None` when none
/// does or the encoder refuses them all (the caller re-encodes everything instead).
pub fn smart_cut(
    src: &Path,
    skip: usize,
    take: usize,
    cuts: &CutPoints,
    candidates: &[Encoding],
    scratch: &Path,
) -> Result<Option<SmartCut>, VideoError> {
    let end = skip + take;
    let copy_from = (skip..end).find(|f| cuts.can_start(*f)).unwrap_or(end);
    let copy_to = (copy_from..=end)
        .rev()
        .find(|f| cuts.can_end(*f))
        .unwrap_or(copy_from);
    let range = |skip: usize, to: usize| ConcatInput {
        path: src.to_path_buf(),
        skip,
        take: Some(to - skip),
    };
    let mut pieces = Vec::new();
    if skip < copy_from {
        pieces.push((range(skip, copy_from), true));
    }
    if copy_from < copy_to {
        pieces.push((range(copy_from, copy_to), false));
    }
    if copy_to < end {
        pieces.push((range(copy_to.max(skip), end), true));
    }
    if pieces.iter().all(|(_, encode)| !encode) {
        let inputs = pieces.into_iter().map(|(p, _)| p).collect();
        return Ok(Some(SmartCut {
            inputs,
            candidate: None,
            reencoded: 0,
        }));
    }
    let info = probe(src)?;
    // Headers depend on the settings, not on the frames: a few frames tell which
    // candidate reproduces the source's before any piece is encoded whole.
    let Some(candidate) = matching_candidate(src, &info, &pieces, candidates, scratch) else {
        return Ok(None);
    };
    let mut inputs = Vec::new();
    let mut reencoded = 0;
    for (piece, encode) in &pieces {
        if !encode {
            inputs.push(piece.clone());
            continue;
        }
        let path = scratch.join(format!("{}-{}.mp4", stem(src), piece.skip));
        let Some(frames) = encode_piece(piece, candidates[candidate], &info, &path) else {
            for made in inputs.iter().filter(|i| i.path != src) {
                let _ = fs_err::remove_file(&made.path);
            }
            return Ok(None);
        };
        reencoded += frames;
        inputs.push(ConcatInput {
            path,
            skip: 0,
            take: Some(frames),
        });
    }
    Ok(Some(SmartCut {
        inputs,
        candidate: Some(candidate),
        reencoded,
    }))
}

/// The first of `candidates` whose encoding of the first frames (at most 8) of the
/// first piece to re-encode has the source's stream headers.
fn matching_candidate(
    src: &Path,
    info: &crate::VideoInfo,
    pieces: &[(ConcatInput, bool)],
    candidates: &[Encoding],
    scratch: &Path,
) -> Option<usize> {
    const PROBE_FRAMES: usize = 8;
    let (first, _) = pieces.iter().find(|(_, encode)| *encode)?;
    let probe_piece = ConcatInput {
        take: first.take.map(|t| t.min(PROBE_FRAMES)),
        ..first.clone()
    };
    let path = scratch.join(format!("{}-probe.mp4", stem(src)));
    let found = candidates
        .iter()
        .position(|c| encode_piece(&probe_piece, *c, info, &path).is_some());
    let _ = fs_err::remove_file(&path);
    found
}

/// Encodes `piece` with `encoding` into `path`; its frames where the result's stream
/// headers equal the source's (`info`), else `None` (nothing left at `path`). A setting
/// this ffmpeg's encoder refuses (SVT-AV1 1.4 wants 64 px at least) is no match either.
fn encode_piece(
    piece: &ConcatInput,
    encoding: Encoding,
    info: &crate::VideoInfo,
    path: &Path,
) -> Option<usize> {
    let spec = VideoSpec {
        width: info.width,
        height: info.height,
        fps: info.fps.round() as u32,
        codec: encoding.codec,
    };
    let keyframes = Keyframes {
        interval: encoding.interval,
        at: Vec::new(),
    };
    let made = transcode(std::slice::from_ref(piece), path, spec, &keyframes).ok();
    let matches = made.is_some() && probe(path).is_ok_and(|p| p.extradata == info.extradata);
    if !matches {
        let _ = fs_err::remove_file(path);
    }
    made.filter(|_| matches)
}

/// A file's name without its extension, for the names of files made from it.
fn stem(path: &Path) -> String {
    path.file_stem()
        .map_or_else(String::new, |s| s.to_string_lossy().into_owned())
}

/// What an H.264 video's x264 recorded of its settings (x264 writes its options into
/// the first keyframe: `x264 - core 164 ... options: ... keyint=5 ... crf=21.0 ...`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct X264Settings {
    /// `crf=`, rounded (absent for other rate controls).
    pub crf: Option<u8>,
    /// `keyint=`: the keyframe interval (`-g`).
    pub keyint: Option<u32>,
}

/// The x264 settings recorded in the first megabyte of `path`; `None` when there are
/// none (another encoder, or x264's message left out).
pub fn x264_settings(path: &Path) -> Result<Option<X264Settings>, VideoError> {
    let mut head = Vec::new();
    fs_err::File::open(path)
        .and_then(|f| f.take(1 << 20).read_to_end(&mut head))
        .map_err(|source| VideoError::Io {
            path: path.into(),
            source,
        })?;
    let marker = b"x264 - core ";
    let Some(at) = head.windows(marker.len()).position(|w| w == marker) else {
        return Ok(None);
    };
    let text: String = head[at..]
        .iter()
        .take_while(|b| **b != 0)
        .take(4096)
        .map(|b| *b as char)
        .collect();
    let options = text.split("options:").nth(1).unwrap_or("");
    let value = |key: &str| {
        options
            .split_whitespace()
            .find_map(|kv| kv.strip_prefix(key)?.strip_prefix('='))
    };
    Ok(Some(X264Settings {
        crf: value("crf")
            .and_then(|v| v.parse::<f64>().ok())
            .map(|c| c.round().clamp(0.0, 63.0) as u8),
        keyint: value("keyint").and_then(|v| v.parse().ok()),
    }))
}

/// How a video's metadata says it was encoded (LeRobot's `video.crf`, `video.preset`,
/// `video.g`), where it says.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct StatedEncoding {
    /// Constant rate factor.
    pub crf: Option<u8>,
    /// x264's preset name or SVT-AV1's preset number.
    pub preset: Option<String>,
    /// Keyframe interval.
    pub interval: Option<u32>,
}

/// The encoder settings to try, in order, for frames that must join a stream of codec
/// `codec` (`h264`, `av1`; none for others) by stream copy ([`smart_cut`]): the crf and
/// keyframe interval x264 `recorded` in the file, else the `stated` ones, else the
/// usual ones (x264's crf 23, lerobot's AV1 crf 30); the stated preset first, then the
/// codec's other presets; each with the interval, then without.
pub fn candidate_encodings(
    codec: &str,
    stated: &StatedEncoding,
    recorded: Option<X264Settings>,
) -> Vec<Encoding> {
    let crf = recorded.and_then(|r| r.crf).or(stated.crf);
    let g = recorded.and_then(|r| r.keyint).or(stated.interval);
    let intervals = if g.is_some() {
        vec![g, None]
    } else {
        vec![None, Some(2)]
    };
    let codecs: Vec<crate::Codec> = match codec {
        "h264" => {
            let named = stated.preset.as_deref().and_then(|p| p.parse().ok());
            named
                .into_iter()
                .chain(crate::X264Preset::ALL)
                .map(|preset| crate::Codec::H264 {
                    crf: crf.unwrap_or(23),
                    preset,
                })
                .collect()
        }
        "av1" => {
            let named = stated.preset.as_deref().and_then(|p| p.parse::<u8>().ok());
            named
                .filter(|p| *p <= 13)
                .into_iter()
                .chain([12, 8, 10, 6, 4])
                .map(|preset| crate::Codec::Av1 {
                    crf: crf.unwrap_or(30),
                    preset,
                })
                .collect()
        }
        _ => Vec::new(),
    };
    let mut all: Vec<Encoding> = Vec::new();
    for codec in codecs {
        for interval in &intervals {
            let e = Encoding {
                codec,
                interval: *interval,
            };
            if !all.contains(&e) {
                all.push(e);
            }
        }
    }
    all
}
