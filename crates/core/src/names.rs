//! What a name that comes from input data may be once it becomes a file or folder name:
//! episode ids, task ids, camera names, topic names, evaluation folder names. Input
//! data is never a path: one function, [`safe_name`], decides, and every place where
//! such a name meets the file system asks it.

/// The longest safe name, in bytes. Names are joined (`<task>_<episode>.mcap`) and
/// suffixed (`<episode>__r00`, `.<name>.partial-<pid>`) into file names that must stay
/// under the 255 bytes of a file system's name.
pub const MAX_NAME_BYTES: usize = 100;

/// A name from input data that cannot be a file or folder name.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{what} {shown} cannot be a file name: {why}", shown = shown(name))]
pub struct UnsafeName {
    /// What the name names (`episode id`, `task id`, `camera name`...).
    pub what: &'static str,
    /// The name as given.
    pub name: String,
    /// Why it is refused.
    pub why: &'static str,
}

/// The name quoted for a message: control characters escaped, shortened past 60
/// characters.
fn shown(name: &str) -> String {
    let head: String = name.chars().take(60).collect();
    let quoted = format!("\"{}\"", head.escape_debug());
    if name.chars().count() > 60 {
        format!("{quoted}... ({} bytes)", name.len())
    } else {
        quoted
    }
}

/// `name` when it is safe as one file or folder name, else why not. Safe: not empty, at
/// most [`MAX_NAME_BYTES`] bytes, no path separator (`/` or `\`), not `.` or `..` and not
/// starting with `.` (hidden: discovery never reads such a folder, and the project's own
/// staging and lock files are named so), no NUL or other control character (a line
/// break in a name breaks logs, tables and CSV files). Any other character, unicode,
/// spaces and quotes included, is fine.
pub fn safe_name<'a>(what: &'static str, name: &'a str) -> Result<&'a str, UnsafeName> {
    let why = if name.is_empty() {
        Some("it is empty")
    } else if name.len() > MAX_NAME_BYTES {
        Some("it is longer than 100 bytes")
    } else if name.contains(['/', '\\']) {
        Some("it holds a path separator")
    } else if name == "." || name == ".." {
        Some("it names a folder, not a file")
    } else if name.starts_with('.') {
        Some("it starts with '.' (a hidden name)")
    } else if name.chars().any(char::is_control) {
        Some("it holds a control character (NUL, a line break...)")
    } else {
        None
    };
    match why {
        None => Ok(name),
        Some(why) => Err(UnsafeName {
            what,
            name: name.to_owned(),
            why,
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_names_and_paths_are_refused() {
        for ok in [
            "episode_000000",
            "click_mouse",
            "épisode «1» 'quoted' \"twice\"",
            "a b",
            "x..y",
            &"é".repeat(50),
        ] {
            assert_eq!(safe_name("episode id", ok), Ok(ok), "{ok}");
        }
        for (bad, why) in [
            ("", "empty"),
            ("../../../x", "separator"),
            ("/abs/x", "separator"),
            ("a\\b", "separator"),
            ("..", "folder"),
            (".", "folder"),
            (".hidden", "hidden"),
            ("a\0b", "control"),
            ("line\nbreak", "control"),
            (&"x".repeat(101), "100 bytes"),
            (&"é".repeat(51), "100 bytes"),
        ] {
            let e = safe_name("episode id", bad).unwrap_err();
            assert!(e.why.contains(why), "{bad:?}: {e}");
            assert!(e.to_string().starts_with("episode id \""), "{e}");
        }
        let long = safe_name("task id", &"y".repeat(10_000)).unwrap_err();
        assert!(long.to_string().contains("(10000 bytes)"), "{long}");
        assert!(long.to_string().len() < 200, "{long}");
        let nul = safe_name("camera name", "a\0b").unwrap_err().to_string();
        assert!(nul.contains("\\0"), "{nul}");
    }
}
