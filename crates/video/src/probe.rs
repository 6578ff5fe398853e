//! What a video holds: codec, size, rate, frames, keyframes and packet times. Asked of
//! ffprobe where there is one, else of ffmpeg alone (`-c copy -f framecrc` and the
//! input's stream line), as with imageio-ffmpeg's static build, which has no ffprobe.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::{VideoError, ffmpeg_program, locate_ffprobe, run, run_output};

/// What a video's first stream is.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VideoInfo {
    /// Codec name (`h264`, `av1`).
    pub codec: String,
    /// Codec profile (`High`), when reported.
    pub profile: Option<String>,
    /// Pixel format (`yuv420p`).
    pub pix_fmt: String,
    /// Width.
    pub width: u32,
    /// Height.
    pub height: u32,
    /// Frames per second.
    pub fps: f64,
    /// Number of frames (counted by reading the packets).
    pub frames: u64,
    /// The codec's out-of-band parameters (H.264's SPS/PPS) as `<bytes>:<adler32>`:
    /// files whose fingerprints differ must not share one file by stream copy.
    #[serde(default)]
    pub extradata: String,
    /// Indices (in presentation order) of the frames that are keyframes, where decoding
    /// and a stream copy cut can start. Not serialized.
    #[serde(skip)]
    pub keyframes: Vec<usize>,
}

/// One packet of the first video stream.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Packet {
    /// Presentation time, seconds.
    pub pts: f64,
    /// Decoding time, seconds (the presentation time where the file has none).
    pub dts: f64,
    /// A keyframe (where decoding, and a stream copy cut, can start).
    pub key: bool,
}

/// Codec, size, rate, frame count and extradata of a video.
pub fn probe(path: &Path) -> Result<VideoInfo, VideoError> {
    match locate_ffprobe() {
        Some(ffprobe) => probe_with_ffprobe(ffprobe, path),
        None => probe_with_ffmpeg_alone(path),
    }
}

/// What [`probe`] answers where no ffprobe is found: ffmpeg's own listing of the stream.
pub fn probe_with_ffmpeg_alone(path: &Path) -> Result<VideoInfo, VideoError> {
    Ok(FrameCrc::read(path)?.info)
}

/// Presentation timestamps (seconds) of every frame of the first video stream, in
/// presentation order.
pub fn frame_times(path: &Path) -> Result<Vec<f64>, VideoError> {
    Ok(packets(path)?.iter().map(|p| p.pts).collect())
}

/// Indices (in presentation order) of the frames that are keyframes ([`VideoInfo::keyframes`]).
pub fn keyframe_indices(path: &Path) -> Result<Vec<usize>, VideoError> {
    Ok(probe(path)?.keyframes)
}

/// Sorts `packets` into presentation order.
fn in_presentation_order(mut packets: Vec<Packet>) -> Vec<Packet> {
    packets.sort_by(|a, b| a.pts.total_cmp(&b.pts));
    packets
}

/// Indices of the keyframes among `packets` (in presentation order).
fn keyframes_of(packets: &[Packet]) -> Vec<usize> {
    packets
        .iter()
        .enumerate()
        .filter_map(|(i, p)| p.key.then_some(i))
        .collect()
}

/// The first video stream's packets, in presentation order.
fn packets(path: &Path) -> Result<Vec<Packet>, VideoError> {
    Ok(in_presentation_order(packets_in_decoding_order(path)?))
}

/// The first video stream's packets in decoding order (the order they are stored),
/// where a stream-copy cut's end is decided.
pub fn packets_in_decoding_order(path: &Path) -> Result<Vec<Packet>, VideoError> {
    match locate_ffprobe() {
        Some(ffprobe) => {
            let ask = ["-show_entries", PACKET_ENTRIES];
            let out = ask_ffprobe(ffprobe, path, &ask, "json")?;
            let json = parse_json(path, &out)?;
            Ok(packets_of(&json))
        }
        None => Ok(FrameCrc::read(path)?.packets),
    }
}

/// What ffprobe is asked of each packet.
const PACKET_ENTRIES: &str = "packet=pts_time,dts_time,flags";

/// The packets of ffprobe's JSON answer, in the order listed (decoding order).
fn packets_of(json: &serde_json::Value) -> Vec<Packet> {
    json["packets"]
        .as_array()
        .into_iter()
        .flatten()
        .filter_map(|p| {
            let pts: f64 = p["pts_time"].as_str()?.parse().ok()?;
            Some(Packet {
                pts,
                dts: p["dts_time"]
                    .as_str()
                    .and_then(|d| d.parse().ok())
                    .unwrap_or(pts),
                key: p["flags"].as_str()?.contains('K'),
            })
        })
        .collect()
}

fn parse_json(path: &Path, out: &[u8]) -> Result<serde_json::Value, VideoError> {
    serde_json::from_slice(out).map_err(|e| failed(path, "ffprobe", &e.to_string()))
}

/// ffprobe's answer about the first video stream of `path`: `-v error -select_streams
/// v:0`, then `ask`, in the output format `format`.
fn ask_ffprobe(
    ffprobe: PathBuf,
    path: &Path,
    ask: &[&str],
    format: &str,
) -> Result<Vec<u8>, VideoError> {
    let p = path.to_string_lossy();
    let mut args = vec!["-v", "error", "-select_streams", "v:0"];
    args.extend_from_slice(ask);
    args.extend_from_slice(&["-of", format, &p]);
    run(ffprobe, &args, path)
}

fn probe_with_ffprobe(ffprobe: PathBuf, path: &Path) -> Result<VideoInfo, VideoError> {
    let ask = [
        "-count_packets",
        "-show_streams",
        "-show_data",
        "-show_entries",
        PACKET_ENTRIES,
    ];
    let out = ask_ffprobe(ffprobe, path, &ask, "json")?;
    let json = parse_json(path, &out)?;
    let s = json["streams"]
        .get(0)
        .ok_or_else(|| failed(path, "ffprobe", "no video stream"))?;
    let rate = s["avg_frame_rate"].as_str().unwrap_or("0/1");
    let fps = match rate.split_once('/') {
        Some((n, d)) => n.parse::<f64>().unwrap_or(0.0) / d.parse::<f64>().unwrap_or(1.0).max(1e-9),
        None => rate.parse().unwrap_or(0.0),
    };
    let extradata = hexdump_bytes(s["extradata"].as_str().unwrap_or(""));
    Ok(VideoInfo {
        codec: s["codec_name"].as_str().unwrap_or("").into(),
        profile: s["profile"].as_str().map(Into::into),
        pix_fmt: s["pix_fmt"].as_str().unwrap_or("").into(),
        width: s["width"].as_u64().unwrap_or(0) as u32,
        height: s["height"].as_u64().unwrap_or(0) as u32,
        fps,
        frames: s["nb_read_packets"]
            .as_str()
            .and_then(|n| n.parse().ok())
            .unwrap_or(0),
        extradata: fingerprint(extradata.len(), adler32(&extradata)),
        keyframes: keyframes_of(&packets_of(&json)),
    })
}

/// `<bytes>:<adler32>`, as ffmpeg's framecrc prints extradata (Adler-32 from 0).
fn fingerprint(len: usize, adler: u32) -> String {
    format!("{len}:{adler:08x}")
}

fn adler32(bytes: &[u8]) -> u32 {
    let mut a = adler2::Adler32::from_checksum(0);
    a.write_slice(bytes);
    a.checksum()
}

/// The bytes of ffprobe's `-show_data` hex dump (`00000000: 0164 000c ...  .d..`).
fn hexdump_bytes(dump: &str) -> Vec<u8> {
    let mut bytes = Vec::new();
    for line in dump.lines() {
        let Some((_, rest)) = line.split_once(": ") else {
            continue;
        };
        // Eight groups of up to four hex digits, then two spaces and the ASCII column.
        let hex = rest.split("  ").next().unwrap_or("");
        for group in hex.split_whitespace() {
            for pair in group.as_bytes().chunks(2) {
                if let Ok(b) = u8::from_str_radix(std::str::from_utf8(pair).unwrap_or(""), 16) {
                    bytes.push(b);
                }
            }
        }
    }
    bytes
}

fn failed(path: &Path, program: &str, message: &str) -> VideoError {
    VideoError::Failed {
        program: program.into(),
        path: path.into(),
        message: message.into(),
    }
}

/// What ffmpeg alone says about a video: its framecrc listing of the stream-copied
/// packets (time base, extradata, each packet's pts and flags) and the stream line it
/// logs for the input (`Video: h264 (High) (avc1 / 0x31637661), yuv420p(progressive),
/// 224x224, 47 kb/s, 30 fps, ...`).
struct FrameCrc {
    info: VideoInfo,
    /// In decoding order, as listed.
    packets: Vec<Packet>,
}

impl FrameCrc {
    fn read(path: &Path) -> Result<Self, VideoError> {
        let p = path.to_string_lossy();
        let args = [
            "-hide_banner",
            "-nostdin",
            "-i",
            &p,
            "-map",
            "0:v:0",
            "-c",
            "copy",
            "-f",
            "framecrc",
            "-",
        ];
        let out = run_output(ffmpeg_program(), &args, path)?;
        let log = String::from_utf8_lossy(&out.stderr);
        let stream = log
            .lines()
            .find(|l| l.contains("Stream #0:") && l.contains(": Video: "))
            .ok_or_else(|| failed(path, "ffmpeg", "no video stream"))?;
        let listing = String::from_utf8_lossy(&out.stdout);
        Self::parse(stream, &listing).ok_or_else(|| {
            failed(
                path,
                "ffmpeg",
                &format!("could not read the stream line {stream:?}"),
            )
        })
    }

    fn parse(stream: &str, listing: &str) -> Option<Self> {
        let video = stream.split_once(": Video: ")?.1;
        let parts = split_top_level(video);
        let head = parts.first()?;
        let codec = head.split_whitespace().next()?.to_owned();
        // `h264 (High) (avc1 / 0x...)`, `av1 (libdav1d) (Main) (av01 / ...)`: the profile
        // is the last group before the codec tag's.
        let groups: Vec<&str> = head
            .split('(')
            .skip(1)
            .map(|g| g.trim().trim_end_matches(')'))
            .filter(|g| !g.contains(" / 0x"))
            .collect();
        let profile = groups.last().map(|g| (*g).to_owned());
        let pix_fmt = parts.get(1)?.split('(').next()?.trim().to_owned();
        let (width, height) = parts.iter().find_map(|p| {
            let size = p.split_whitespace().next()?;
            let (w, h) = size.split_once('x')?;
            Some((w.parse().ok()?, h.parse().ok()?))
        })?;
        let fps = parts
            .iter()
            .find_map(|p| p.strip_suffix(" fps")?.trim().parse().ok())
            .unwrap_or(0.0);
        let mut time_base = 0.0;
        let mut extradata = fingerprint(0, 0);
        let mut packets = Vec::new();
        for line in listing.lines() {
            if let Some(tb) = line.strip_prefix("#tb 0: ") {
                let (n, d) = tb.trim().split_once('/')?;
                time_base = n.parse::<f64>().ok()? / d.parse::<f64>().ok()?;
            } else if let Some(e) = line.strip_prefix("#extradata 0:") {
                let (len, crc) = e.split_once(',')?;
                let crc = u32::from_str_radix(crc.trim().trim_start_matches("0x"), 16).ok()?;
                extradata = fingerprint(len.trim().parse().ok()?, crc);
            } else if !line.starts_with('#') {
                let fields: Vec<&str> = line.split(',').map(str::trim).collect();
                let dts: i64 = fields.get(1)?.parse().ok()?;
                let pts: i64 = fields.get(2)?.parse().ok()?;
                // framecrc prints `F=0x..` only for flags other than "keyframe" alone.
                let key = fields.get(6).is_none_or(|f| {
                    f.strip_prefix("F=0x")
                        .and_then(|h| u32::from_str_radix(h, 16).ok())
                        .is_some_and(|flags| flags & 1 == 1)
                });
                packets.push(Packet {
                    pts: pts as f64 * time_base,
                    dts: dts as f64 * time_base,
                    key,
                });
            }
        }
        let info = VideoInfo {
            codec,
            profile,
            pix_fmt,
            width,
            height,
            fps,
            frames: packets.len() as u64,
            extradata,
            keyframes: keyframes_of(&in_presentation_order(packets.clone())),
        };
        Some(Self { info, packets })
    }
}

/// Splits `a (b, c), d, e` at the commas outside parentheses.
fn split_top_level(s: &str) -> Vec<String> {
    let (mut parts, mut current, mut depth) = (Vec::new(), String::new(), 0i32);
    for c in s.chars() {
        match c {
            '(' | '[' => depth += 1,
            ')' | ']' => depth -= 1,
            ',' if depth == 0 => {
                parts.push(current.trim().to_owned());
                current.clear();
                continue;
            }
            _ => {}
        }
        current.push(c);
    }
    parts.push(current.trim().to_owned());
    parts
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_stream_line_and_listing_of_ffmpeg_alone_give_what_ffprobe_gives() {
        let stream = "  Stream #0:0[0x1](und): Video: h264 (High) (avc1 / 0x31637661), \
                      yuv420p(progressive), 224x224, 47 kb/s, 30 fps, 30 tbr, 15360 tbn (default)";
        let listing = "#extradata 0:       44, 0x20940f51\n#tb 0: 1/15360\n\
                       #media_type 0: video\n#codec_id 0: h264\n\
                       0,      -1024,          0,      512,     7195, 0x97ae94e0\n\
                       0,       -512,       2048,      512,      235, 0xcc6b7768, F=0x0\n\
                       0,          0,       1024,      512,      103, 0xe43e314e, F=0x0\n\
                       0,        512,        512,      512,       57, 0xd1c01a96, F=0x1\n";
        let crc = FrameCrc::parse(stream, listing).unwrap();
        assert_eq!(crc.info.codec, "h264");
        assert_eq!(crc.info.profile.as_deref(), Some("High"));
        assert_eq!(crc.info.pix_fmt, "yuv420p");
        assert_eq!((crc.info.width, crc.info.height), (224, 224));
        assert_eq!(crc.info.fps, 30.0);
        assert_eq!(crc.info.frames, 4);
        assert_eq!(crc.info.extradata, "44:20940f51");
        let keys: Vec<bool> = crc.packets.iter().map(|p| p.key).collect();
        assert_eq!(keys, [true, false, false, true]);
        assert!((crc.packets[1].pts - 2048.0 / 15360.0).abs() < 1e-12);
    }

    #[test]
    fn hexdumps_read_back_to_their_bytes() {
        let dump = "\n00000000: 0164 000c ffe1 0017 6764 000c acd9 4387  .d......gd....C.\n\
                    00000010: 6840 00                                  h@.\n";
        assert_eq!(
            hexdump_bytes(dump),
            [
                0x01, 0x64, 0x00, 0x0c, 0xff, 0xe1, 0x00, 0x17, 0x67, 0x64, 0x00, 0x0c, 0xac, 0xd9,
                0x43, 0x87, 0x68, 0x40, 0x00
            ]
        );
    }
}
