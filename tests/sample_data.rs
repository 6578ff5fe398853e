//! The shipped samples are what their README says makes them, today: the shell block of
//! `datasets/demos/README.md` runs as written (in a temporary folder, this build's
//! `dexjoco-data` on PATH), and every file it writes equals the shipped one byte for
//! byte. A planner change that alters a sample fails here, naming the files, until the
//! samples are made again with those commands.

use std::collections::BTreeMap;
use std::path::Path;
use std::process::Command;

mod common;

/// The first ```sh block of a Markdown file.
fn sh_block(markdown: &str) -> String {
    let start = markdown
        .find("```sh\n")
        .expect("the README has a ```sh block")
        + "```sh\n".len();
    let len = markdown[start..].find("```").expect("the block is closed");
    markdown[start..start + len].to_owned()
}

#[test]
fn the_shipped_samples_are_what_their_readme_commands_make_today() {
    let root = dexjoco_testkit::workspace_root();
    let readme = fs_err::read_to_string(root.join("datasets/demos/README.md")).unwrap();
    let script = sh_block(&readme);
    assert!(
        script.contains("dexjoco-data scripted") && script.contains("datasets/demos"),
        "{script}"
    );
    let tmp = tempfile::tempdir().unwrap();
    let bin = Path::new(env!("CARGO_BIN_EXE_dexjoco-data"))
        .parent()
        .unwrap();
    let path = format!(
        "{}:{}",
        bin.display(),
        std::env::var("PATH").unwrap_or_default()
    );
    // The README's commands.
    common::succeeds(
        Command::new("sh")
            .args(["-e", "-c", &script])
            .env("PATH", path)
            .current_dir(tmp.path()),
    );
    let made = dexjoco_testkit::file_tree(&tmp.path().join("datasets/demos"));
    let mut shipped = dexjoco_testkit::file_tree(&root.join("datasets/demos"));
    shipped.remove("README.md");
    let names = |t: &BTreeMap<String, Vec<u8>>| t.keys().cloned().collect::<Vec<_>>();
    assert_eq!(
        names(&made),
        names(&shipped),
        "the commands make other files than datasets/demos ships"
    );
    let stale: Vec<&String> = made
        .iter()
        .filter(|(name, bytes)| shipped[*name] != **bytes)
        .map(|(name, _)| name)
        .collect();
    assert!(
        stale.is_empty(),
        "datasets/demos is stale: today's planners make other bytes for {stale:#?}\n\
         make the samples again with the commands in datasets/demos/README.md (from the \
         checkout's root), then redo what depends on them (docs: DEXJOCO_BLESS=1 cargo test --test docs)"
    );
}
