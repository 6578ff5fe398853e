//! Zarr v2 pieces shared by every store this project writes (the raw layout's
//! `replay.zarr` here, convert's Diffusion Policy `replay_buffer.zarr`): array metadata as
//! zarr-python 2 writes it, and empty groups.

use std::sync::Arc;

use serde_json::{Value, json};
use zarrs::array::{ArrayMetadata, ArrayMetadataV2};
use zarrs::filesystem::FilesystemStore;
use zarrs::group::{Group, GroupMetadata, GroupMetadataOptions};
use zarrs::metadata::v2::GroupMetadataV2;

/// A Blosc compressor as numcodecs describes it in `.zarray`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Blosc {
    /// Inner codec name (`zstd`, `lz4`, ...).
    pub cname: &'static str,
    /// Compression level, 0..=9.
    pub clevel: u8,
    /// 0 no shuffle, 1 byte shuffle, 2 bit shuffle.
    pub shuffle: u8,
}

impl Blosc {
    /// The DexJoCo recorder's compressor: zstd, level 5, bit shuffle.
    pub const RECORDER: Self = Self {
        cname: "zstd",
        clevel: 5,
        shuffle: 2,
    };
    /// Diffusion Policy's `ReplayBuffer` default: lz4, level 5, no shuffle.
    pub const DIFFUSION_POLICY: Self = Self {
        cname: "lz4",
        clevel: 5,
        shuffle: 0,
    };
}

/// `.zarray` metadata of a C-order array with `.`-separated chunk keys, no filters and a
/// zero fill value (`0.0` for float dtypes such as `<f8`, `0` otherwise).
pub fn array_metadata(
    shape: &[u64],
    chunks: &[u64],
    dtype: &str,
    compressor: Option<Blosc>,
) -> Result<ArrayMetadata, String> {
    let compressor = match compressor {
        Some(b) => json!({
            "id": "blosc",
            "cname": b.cname,
            "clevel": b.clevel,
            "shuffle": b.shuffle,
            "blocksize": 0,
        }),
        None => Value::Null,
    };
    let fill = if dtype.get(1..2) == Some("f") {
        json!(0.0)
    } else {
        json!(0)
    };
    let meta = json!({
        "zarr_format": 2,
        "shape": shape,
        "chunks": chunks,
        "dtype": dtype,
        "compressor": compressor,
        "fill_value": fill,
        "order": "C",
        "filters": null,
        "dimension_separator": ".",
    });
    serde_json::from_value::<ArrayMetadataV2>(meta)
        .map(ArrayMetadata::V2)
        .map_err(|e| format!("building .zarray: {e}"))
}

/// Writes an empty v2 group (`.zgroup`) at each of `paths` (e.g. `["/", "/data"]`).
pub fn create_groups(store: &Arc<FilesystemStore>, paths: &[&str]) -> Result<(), String> {
    for path in paths {
        Group::new_with_metadata(
            store.clone(),
            path,
            GroupMetadata::V2(GroupMetadataV2::new()),
        )
        .map_err(|e| e.to_string())?
        .store_metadata_opt(&GroupMetadataOptions::default())
        .map_err(|e| e.to_string())?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The `.zarray` JSON (the inner v2 document, as written to disk).
    fn json_of(meta: ArrayMetadata) -> Value {
        match meta {
            ArrayMetadata::V2(v2) => serde_json::to_value(v2).unwrap(),
            ArrayMetadata::V3(_) => panic!("a v3 document"),
        }
    }

    #[test]
    fn metadata_is_what_zarr_python_2_writes() {
        let m = json_of(array_metadata(&[5, 3], &[5, 3], "<f8", Some(Blosc::RECORDER)).unwrap());
        assert_eq!(
            m,
            json!({
                // zarrs adds this key; zarr-python ignores it.
                "node_type": "array",
                "zarr_format": 2,
                "shape": [5, 3],
                "chunks": [5, 3],
                "dtype": "<f8",
                "compressor": {"id": "blosc", "cname": "zstd", "clevel": 5, "shuffle": 2, "blocksize": 0},
                "fill_value": 0.0,
                "order": "C",
                "filters": null,
                "dimension_separator": ".",
            })
        );
        let ends = json_of(array_metadata(&[1], &[1024], "<i8", None).unwrap());
        assert_eq!(ends["fill_value"], json!(0));
        assert_eq!(ends["compressor"], Value::Null);
        let img = json_of(
            array_metadata(
                &[0, 4, 4, 3],
                &[1, 4, 4, 3],
                "|u1",
                Some(Blosc::DIFFUSION_POLICY),
            )
            .unwrap(),
        );
        assert_eq!(img["fill_value"], json!(0));
        assert_eq!(img["compressor"]["cname"], "lz4");
    }
}
