//! Writing an episode as a raw folder, laid out as the reference recorder (zarr-python 2)
//! lays it out, with the episode's own instruction in `.zattrs` when it has one.

use super::*;

pub(super) fn zarr_write_err(at: &Location) -> impl Fn(String) -> FormatError + '_ {
    move |message| FormatError::Zarr {
        at: at.clone(),
        message,
    }
}

/// The root group's attribute file of a Zarr v2 store.
pub(super) const ATTRIBUTES_FILE: &str = ".zattrs";

/// The instruction an episode of `task` has of its own, to be stored with it: its
/// prompt unless that is empty or the task's prompt (which applies anyway when none is
/// stored, so recordings of the task's prompt write what the recorder writes).
pub fn own_instruction<'e>(episode: &'e Episode, task: &TaskSpec) -> Option<&'e str> {
    let prompt = episode.prompt.as_str();
    (!prompt.trim().is_empty() && prompt != task.prompt).then_some(prompt)
}

/// Writes an episode of `task` as a raw folder under `dir`: `replay.zarr`
/// ([`write_replay_zarr`]) and, when it has one, its own instruction
/// ([`own_instruction`]) as the [`INSTRUCTION_ATTRIBUTE`] of `replay.zarr/.zattrs`.
pub fn write_raw_episode(dir: &Path, episode: &Episode, task: &TaskSpec) -> Result<()> {
    write_replay_zarr(dir, episode)?;
    let Some(instruction) = own_instruction(episode, task) else {
        return Ok(());
    };
    let zarr = dir.join(REPLAY_ZARR);
    let at = Location::episode(&episode.id)
        .path(zarr.join(ATTRIBUTES_FILE))
        .field(INSTRUCTION_ATTRIBUTE);
    let err = zarr_write_err(&at);
    let store = Arc::new(FilesystemStore::new(&zarr).map_err(|e| err(e.to_string()))?);
    let mut attributes = serde_json::Map::new();
    attributes.insert(INSTRUCTION_ATTRIBUTE.to_owned(), instruction.into());
    Group::new_with_metadata(
        store,
        "/",
        GroupMetadata::V2(GroupMetadataV2::new().with_attributes(attributes)),
    )
    .map_err(|e| err(e.to_string()))?
    .store_metadata()
    .map_err(|e| err(e.to_string()))
}

/// Writes `replay.zarr` of one episode under `dir` (created), as the recorder does:
/// float64 arrays, Blosc zstd clevel 5 bitshuffle, one chunk per episode up to 2 MB,
/// `meta/episode_ends` int64 uncompressed in chunks of 1024, no `.zattrs` (the arrays
/// only: [`write_raw_episode`] also keeps the episode's own instruction).
pub fn write_replay_zarr(dir: &Path, ep: &Episode) -> Result<()> {
    let zarr = dir.join(REPLAY_ZARR);
    let at = Location::episode(&ep.id).path(&zarr);
    let err = zarr_write_err(&at);
    fs_err::create_dir_all(&zarr).map_err(io_err("create", &zarr))?;
    let store = Arc::new(FilesystemStore::new(&zarr).map_err(|e| err(e.to_string()))?);
    zarr_v2::create_groups(&store, &["/", "/data", "/meta"]).map_err(|e| err(e.to_string()))?;
    let array_opts = ArrayMetadataOptions::default().with_include_zarrs_metadata(false);
    let codec_opts = CodecOptions::default().with_store_empty_chunks(true);
    let frames = ep.len() as u64;
    for (name, a) in &ep.arrays {
        let width = a.width() as u64;
        let per_step = (width as usize * 8).max(1);
        let chunk_frames = ((CHUNK_BYTES / per_step) as u64).min(frames).max(1);
        let (shape, chunks) = if name == Episode::TIMESTAMP && width == 1 {
            (vec![frames], vec![chunk_frames])
        } else {
            (vec![frames, width], vec![chunk_frames, width])
        };
        let meta = zarr_v2::array_metadata(&shape, &chunks, "<f8", Some(Blosc::RECORDER))
            .map_err(|e| err(e.to_string()))?;
        let array = Array::new_with_metadata(store.clone(), &format!("/data/{name}"), meta)
            .map_err(|e| err(e.to_string()))?;
        array
            .store_metadata_opt(&array_opts)
            .map_err(|e| err(e.to_string()))?;
        if frames > 0 {
            array
                .store_array_subset_opt(&array.subset_all(), a.as_slice(), &codec_opts)
                .map_err(|e| err(e.to_string()))?;
        }
    }
    let meta =
        zarr_v2::array_metadata(&[1], &[1024], "<i8", None).map_err(|e| err(e.to_string()))?;
    let array = Array::new_with_metadata(store.clone(), "/meta/episode_ends", meta)
        .map_err(|e| err(e.to_string()))?;
    array
        .store_metadata_opt(&array_opts)
        .map_err(|e| err(e.to_string()))?;
    array
        .store_array_subset_opt(&array.subset_all(), &[frames as i64][..], &codec_opts)
        .map_err(|e| err(e.to_string()))?;
    Ok(())
}
