//! Zarr v2 pieces shared by every store this project writes (the raw layout's
//! `replay.zarr` here, the Diffusion Policy `replay_buffer.zarr` in [`crate::dataset`]):
//! array metadata as zarr-python 2 writes it (through zarrs' typed v2 metadata), and
//! empty groups.

use std::sync::Arc;

use std::num::NonZeroU64;

use zarrs::array::{ArrayMetadata, ArrayMetadataV2};
use zarrs::filesystem::FilesystemStore;
use zarrs::group::{Group, GroupMetadata, GroupMetadataOptions};
use zarrs::metadata::ChunkKeySeparator;
use zarrs::metadata::v2::{
    ArrayMetadataV2Order, DataTypeMetadataV2, FillValueMetadataV2, GroupMetadataV2, MetadataV2,
};

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
) -> Result<ArrayMetadata, ZarrV2Error> {
    let chunks = chunks
        .iter()
        .map(|&c| NonZeroU64::new(c).ok_or(ZarrV2Error::ZeroChunk))
        .collect::<Result<Vec<_>, _>>()?;
    let compressor = compressor
        .map(Blosc::metadata)
        .transpose()
        .map_err(ZarrV2Error::Compressor)?;
    let fill = if dtype.get(1..2) == Some("f") {
        FillValueMetadataV2::from(0.0)
    } else {
        FillValueMetadataV2::from(0u64)
    };
    let meta = ArrayMetadataV2::new(
        shape.to_vec(),
        chunks,
        DataTypeMetadataV2::Simple(dtype.to_owned()),
        fill,
        compressor,
        None,
    )
    .with_order(ArrayMetadataV2Order::C)
    .with_dimension_separator(ChunkKeySeparator::Dot);
    Ok(ArrayMetadata::V2(meta))
}

impl Blosc {
    /// The `compressor` entry of `.zarray`. zarrs makes a v2 codec entry only by reading
    /// one, so it is read from this typed form.
    fn metadata(self) -> Result<MetadataV2, serde_json::Error> {
        #[derive(serde::Serialize)]
        struct Numcodecs {
            id: &'static str,
            cname: &'static str,
            clevel: u8,
            shuffle: u8,
            blocksize: u32,
        }
        let entry = Numcodecs {
            id: "blosc",
            cname: self.cname,
            clevel: self.clevel,
            shuffle: self.shuffle,
            blocksize: 0,
        };
        serde_json::from_value(serde_json::to_value(entry)?)
    }
}

/// Writes an empty v2 group (`.zgroup`) at each of `paths` (e.g. `["/", "/data"]`).
pub fn create_groups(store: &Arc<FilesystemStore>, paths: &[&str]) -> Result<(), ZarrV2Error> {
    for path in paths {
        Group::new_with_metadata(
            store.clone(),
            path,
            GroupMetadata::V2(GroupMetadataV2::new()),
        )?
        .store_metadata_opt(&GroupMetadataOptions::default())?;
    }
    Ok(())
}

/// Why Zarr v2 metadata or groups could not be made.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ZarrV2Error {
    /// A chunk side of 0.
    #[error("building .zarray: a chunk of size 0")]
    ZeroChunk,
    /// The compressor entry could not be built.
    #[error("building .zarray: {0}")]
    Compressor(#[source] serde_json::Error),
    /// A group could not be created.
    #[error(transparent)]
    Group(#[from] zarrs::group::GroupCreateError),
    /// A group's metadata could not be stored.
    #[error(transparent)]
    Storage(#[from] zarrs::storage::StorageError),
}

#[cfg(test)]
mod tests {
    use serde_json::{Value, json};

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

    #[test]
    fn metadata_keys_are_in_zarr_python_2_order() {
        let ArrayMetadata::V2(m) =
            array_metadata(&[0, 2], &[3, 2], "<f8", Some(Blosc::DIFFUSION_POLICY)).unwrap()
        else {
            panic!("a v3 document")
        };
        assert_eq!(
            serde_json::to_string(&m).unwrap(),
            r#"{"node_type":"array","zarr_format":2,"shape":[0,2],"chunks":[3,2],"dtype":"<f8","compressor":{"id":"blosc","cname":"lz4","clevel":5,"shuffle":0,"blocksize":0},"fill_value":0.0,"order":"C","filters":null,"dimension_separator":"."}"#
        );
    }
}
