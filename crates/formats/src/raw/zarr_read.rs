//! Reading a `replay.zarr` store as the recorder wrote it: array metadata, chunks and
//! `meta/episode_ends`, each checked, with errors that name the array and the chunk.

use super::*;

pub(super) struct ArrayInfo {
    pub(super) dtype: Dtype,
    pub(super) shape: Vec<u64>,
    pub(super) chunks: Vec<u64>,
}

/// The largest JSON file read (array metadata, records): larger is no recorder's.
const MAX_JSON_BYTES: u64 = 64 << 20;

pub(super) fn read_json(path: &Path, at: &Location) -> Result<Value> {
    if let Ok(m) = fs_err::metadata(path)
        && m.len() > MAX_JSON_BYTES
    {
        return Err(FormatError::input(
            ProblemCode::Corrupt,
            at,
            format!(
                "'{}' holds {} bytes: no record or array description is larger than {} MB",
                path.display(),
                m.len(),
                MAX_JSON_BYTES >> 20
            ),
        ));
    }
    let bytes = fs_err::read(path).map_err(|e| {
        if e.kind() == std::io::ErrorKind::NotFound {
            FormatError::input(
                ProblemCode::MissingArray,
                at,
                format!("'{}' is missing", path.display()),
            )
        } else {
            FormatError::input(ProblemCode::Unreadable, at, e)
        }
    })?;
    if bytes.is_empty() {
        return Err(FormatError::input(
            ProblemCode::EmptyFile,
            at,
            format!("'{}' is empty", path.display()),
        ));
    }
    serde_json::from_slice(&bytes).map_err(|e| {
        FormatError::input(
            ProblemCode::Corrupt,
            at,
            format!("'{}' is not valid JSON: {e}", path.display()),
        )
    })
}

pub(super) fn array_info(zarr: &Path, key: &str, at: &Location) -> Result<ArrayInfo> {
    let meta = read_json(&zarr.join(key).join(".zarray"), at)?;
    let corrupt = |what: &str| {
        FormatError::input(
            ProblemCode::Corrupt,
            at,
            format!("'.zarray' has no valid {what}"),
        )
    };
    if meta.get("zarr_format").and_then(Value::as_u64) != Some(2) {
        return Err(corrupt("zarr_format 2"));
    }
    let dims = |k: &str| -> Option<Vec<u64>> {
        meta.get(k)?
            .as_array()?
            .iter()
            .map(Value::as_u64)
            .collect::<Option<Vec<_>>>()
    };
    let shape = dims("shape").ok_or_else(|| corrupt("shape"))?;
    let chunks = dims("chunks").ok_or_else(|| corrupt("chunks"))?;
    if chunks.len() != shape.len() || chunks.contains(&0) {
        return Err(corrupt("chunks"));
    }
    let elements = shape
        .iter()
        .try_fold(1u64, |n, d| n.checked_mul(*d))
        .filter(|n| *n <= MAX_ELEMENTS);
    let chunk_count = shape
        .iter()
        .zip(&chunks)
        .try_fold(1u64, |n, (s, c)| n.checked_mul(s.div_ceil(*c)))
        .filter(|n| *n <= MAX_CHUNKS);
    if elements.is_none() || chunk_count.is_none() {
        return Err(FormatError::input(
            ProblemCode::WrongDimensions,
            at,
            format!(
                "shape {shape:?} in chunks {chunks:?} is beyond what an episode holds \
                 (at most {MAX_ELEMENTS} values in {MAX_CHUNKS} chunks)"
            ),
        ));
    }
    let dtype_str = meta.get("dtype").and_then(Value::as_str).unwrap_or("?");
    let dtype = match dtype_str {
        "<f8" | ">f8" => Dtype::F64,
        "<f4" | ">f4" => Dtype::F32,
        "<i8" | ">i8" => Dtype::I64,
        other => {
            return Err(FormatError::input(
                ProblemCode::WrongDtype,
                at,
                format!("dtype '{other}' is not float64 (or the older float32)"),
            ));
        }
    };
    if meta.get("order").and_then(Value::as_str) == Some("F") {
        return Err(FormatError::input(
            ProblemCode::Corrupt,
            at,
            "Fortran-ordered chunks are not written by the recorder",
        ));
    }
    Ok(ArrayInfo {
        dtype,
        shape,
        chunks,
    })
}

/// Keys of every chunk of an array (default `.` separator).
pub(super) fn chunk_keys(info: &ArrayInfo, separator: &str) -> Vec<String> {
    let counts: Vec<u64> = info
        .shape
        .iter()
        .zip(&info.chunks)
        .map(|(s, c)| s.div_ceil(*c))
        .collect();
    let mut keys = vec![String::new()];
    for (d, n) in counts.iter().enumerate() {
        let mut next = Vec::new();
        for k in &keys {
            for i in 0..*n {
                next.push(if d == 0 {
                    i.to_string()
                } else {
                    format!("{k}{separator}{i}")
                });
            }
        }
        keys = next;
    }
    if counts.contains(&0) {
        Vec::new()
    } else {
        keys
    }
}

pub(super) fn open_store(zarr: &Path, at: &Location) -> Result<Arc<FilesystemStore>> {
    FilesystemStore::new(zarr)
        .map(Arc::new)
        .map_err(|e| FormatError::input(ProblemCode::Unreadable, at, e))
}

pub(super) fn zarr_corrupt(at: &Location, e: impl std::fmt::Display) -> FormatError {
    FormatError::input(ProblemCode::Corrupt, at, format!("cannot decode: {e}"))
}

/// Reads one array as f64 (float32 is widened exactly), checking every chunk is present.
pub(super) fn read_array(
    store: &Arc<FilesystemStore>,
    zarr: &Path,
    key: &str,
    info: &ArrayInfo,
    at: &Location,
) -> Result<Vec<f64>> {
    let meta = read_json(&zarr.join(key).join(".zarray"), at)?;
    let sep = meta
        .get("dimension_separator")
        .and_then(Value::as_str)
        .unwrap_or(".");
    for ck in chunk_keys(info, sep) {
        let p = zarr.join(key).join(&ck);
        if !p.is_file() {
            return Err(FormatError::input(
                ProblemCode::MissingArray,
                at,
                format!("chunk file '{}' is missing", p.display()),
            ));
        }
    }
    let array = Array::open(store.clone(), &format!("/{key}")).map_err(|e| zarr_corrupt(at, e))?;
    let subset = array.subset_all();
    Ok(match info.dtype {
        Dtype::F64 => array
            .retrieve_array_subset::<Vec<f64>>(&subset)
            .map_err(|e| zarr_corrupt(at, e))?,
        Dtype::F32 => array
            .retrieve_array_subset::<Vec<f32>>(&subset)
            .map_err(|e| zarr_corrupt(at, e))?
            .into_iter()
            .map(f64::from)
            .collect(),
        Dtype::I64 => {
            return Err(FormatError::input(
                ProblemCode::WrongDtype,
                at,
                "dtype int64 where float64 is expected",
            ));
        }
    })
}

pub(super) fn read_episode_ends(
    store: &Arc<FilesystemStore>,
    zarr: &Path,
    at: &Location,
) -> Result<Vec<i64>> {
    let key = "meta/episode_ends";
    let info = array_info(zarr, key, at)?;
    if info.dtype != Dtype::I64 || info.shape.len() != 1 {
        return Err(FormatError::input(
            ProblemCode::WrongDtype,
            at,
            "episode_ends must be a 1-d int64 array",
        ));
    }
    let array = Array::open(store.clone(), &format!("/{key}")).map_err(|e| zarr_corrupt(at, e))?;
    array
        .retrieve_array_subset::<Vec<i64>>(&array.subset_all())
        .map_err(|e| zarr_corrupt(at, e))
}
