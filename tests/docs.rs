//! Keeps the documentation true to the code: the flag reference in `docs/commands/` is
//! the binary's own `--help` output, every subcommand has a page, and every relative link
//! in README.md and docs/ points at a file (and heading) of this repository.
//!
//! A generated block is a line `<!-- BEGIN GENERATED: dexjoco-data augment --help -->`,
//! a fenced `text` block holding that command's output, and `<!-- END GENERATED -->`.
//! `DEXJOCO_BLESS=1 cargo test --test docs` rewrites every block from the current binary.

use std::collections::BTreeSet;
use std::path::{Component, Path, PathBuf};
use std::process::{Command, Stdio};

/// Opens a generated block; the command follows, then ` -->`.
const BEGIN: &str = "<!-- BEGIN GENERATED: ";
/// Closes a generated block.
const END: &str = "<!-- END GENERATED -->";
/// How to refresh the generated blocks.
const REFRESH: &str = "DEXJOCO_BLESS=1 cargo test --test docs";
/// The width the help is generated at (clap wraps at the terminal's width).
const COLUMNS: &str = "100";

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn blessing() -> bool {
    std::env::var_os("DEXJOCO_BLESS").is_some_and(|v| !v.is_empty() && v != "0")
}

/// The binary's output for `args` as the docs hold it: no terminal and no environment
/// (clap wraps at `COLUMNS` and shows the values of set environment variables), trailing
/// spaces trimmed.
fn help_text(args: &[&str]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_dexjoco-data"))
        .args(args)
        .env_clear()
        .env("COLUMNS", COLUMNS)
        .stdin(Stdio::null())
        .output()
        .expect("the binary runs");
    assert!(
        out.status.success(),
        "dexjoco-data {} failed: {}",
        args.join(" "),
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).expect("help is UTF-8");
    let lines: Vec<&str> = text.lines().map(str::trim_end).collect();
    format!("{}\n", lines.join("\n").trim_end())
}

/// The subcommands a help text lists under `Commands:` (without `help`).
fn subcommands(help: &str) -> Vec<String> {
    help.lines()
        .skip_while(|l| *l != "Commands:")
        .skip(1)
        .take_while(|l| !l.is_empty())
        .filter(|l| l.starts_with("  ") && !l.starts_with("   "))
        .filter_map(|l| l.split_whitespace().next())
        .filter(|name| *name != "help")
        .map(str::to_owned)
        .collect()
}

/// README.md and every Markdown file under docs/, sorted.
fn markdown_files() -> Vec<PathBuf> {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        for entry in std::fs::read_dir(dir).expect("docs/ is readable") {
            let path = entry.expect("docs/ entry").path();
            if path.is_dir() {
                walk(&path, out);
            } else if path.extension().is_some_and(|e| e == "md") {
                out.push(path);
            }
        }
    }
    let mut files = vec![root().join("README.md")];
    walk(&root().join("docs"), &mut files);
    files.sort();
    files
}

fn relative(path: &Path) -> String {
    path.strip_prefix(root())
        .unwrap_or(path)
        .display()
        .to_string()
}

/// A Markdown file with its generated blocks replaced by fresh output.
struct Regenerated {
    /// The file's new text.
    text: String,
    /// The command of every block, in order.
    commands: Vec<String>,
    /// The commands whose block differs from the fresh output.
    stale: Vec<String>,
}

/// Rewrites every generated block of `text` (from `path`) from the binary.
fn regenerate(path: &Path, text: &str) -> Regenerated {
    let mut out = String::new();
    let mut commands = Vec::new();
    let mut stale = Vec::new();
    let mut lines = text.lines();
    while let Some(line) = lines.next() {
        out.push_str(line);
        out.push('\n');
        let Some(command) = line
            .strip_prefix(BEGIN)
            .and_then(|rest| rest.strip_suffix(" -->"))
        else {
            continue;
        };
        let args: Vec<&str> = command.split_whitespace().collect();
        assert_eq!(
            args.first(),
            Some(&"dexjoco-data"),
            "{}: a generated block must run dexjoco-data: {line}",
            relative(path)
        );
        let mut old = Vec::new();
        loop {
            match lines.next() {
                Some(END) => break,
                Some(l) => old.push(l),
                None => panic!("{}: `{line}` has no `{END}`", relative(path)),
            }
        }
        let body = help_text(&args[1..]);
        let fresh = format!("```text\n{body}```\n");
        let was = format!("{}\n", old.join("\n"));
        if fresh != was {
            stale.push(command.to_owned());
        }
        out.push_str(&fresh);
        out.push_str(END);
        out.push('\n');
        commands.push(command.to_owned());
    }
    Regenerated {
        text: out,
        commands,
        stale,
    }
}

/// The help blocks in docs/ are the binary's `--help` output, and every (sub)command
/// has its page with its block.
#[test]
fn generated_help_matches_the_binary() {
    let bless = blessing();
    let mut stale = Vec::new();
    let mut documented = BTreeSet::new();
    for path in markdown_files() {
        let text = std::fs::read_to_string(&path).expect("readable Markdown");
        let regenerated = regenerate(&path, &text);
        if regenerated.text != text {
            if bless {
                std::fs::write(&path, &regenerated.text).expect("writable docs");
            } else {
                stale.extend(
                    regenerated
                        .stale
                        .iter()
                        .map(|c| format!("  {}: `{c}`", relative(&path))),
                );
            }
        }
        documented.extend(regenerated.commands.into_iter().map(|c| (path.clone(), c)));
    }
    assert!(
        stale.is_empty(),
        "the generated help in the docs differs from the binary's output:\n{}\n\
         refresh it with `{REFRESH}` and review the diff",
        stale.join("\n")
    );

    let has_block =
        |page: &Path, command: &str| documented.contains(&(page.to_owned(), command.to_owned()));
    let commands_dir = root().join("docs/commands");
    let index = commands_dir.join("README.md");
    assert!(
        has_block(&index, "dexjoco-data --help"),
        "docs/commands/README.md needs the block `{BEGIN}dexjoco-data --help -->`"
    );
    let mut missing = Vec::new();
    for command in subcommands(&help_text(&["--help"])) {
        let page = commands_dir.join(format!("{command}.md"));
        let mut wanted = vec![format!("dexjoco-data {command} --help")];
        let subs = subcommands(&help_text(&[&command, "--help"]));
        wanted.extend(
            subs.iter()
                .map(|s| format!("dexjoco-data {command} {s} --help")),
        );
        for block in wanted {
            if !has_block(&page, &block) {
                missing.push(format!("  {}: `{BEGIN}{block} -->`", relative(&page)));
            }
        }
    }
    assert!(
        missing.is_empty(),
        "every subcommand needs a page in docs/commands/ with its help block (an empty \
         block between the markers will do; then run `{REFRESH}`):\n{}",
        missing.join("\n")
    );
}

/// A heading's anchor as GitHub makes it: lower case, punctuation dropped, spaces to `-`.
fn slug(heading: &str) -> String {
    heading
        .trim()
        .to_lowercase()
        .chars()
        .filter_map(|c| match c {
            ' ' => Some('-'),
            c if c.is_alphanumeric() || c == '-' || c == '_' => Some(c),
            _ => None,
        })
        .collect()
}

/// Lines outside fenced code blocks, with inline code spans removed.
fn prose_lines(text: &str) -> Vec<String> {
    let mut in_fence = false;
    let mut lines = Vec::new();
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            in_fence = !in_fence;
            continue;
        }
        if !in_fence {
            let kept: String = line
                .split('`')
                .enumerate()
                .filter(|(i, _)| i % 2 == 0)
                .map(|(_, part)| part)
                .collect();
            lines.push(kept);
        }
    }
    lines
}

/// The anchors of a Markdown file's headings (`#` headings outside code blocks).
fn anchors(text: &str) -> BTreeSet<String> {
    let mut seen = BTreeSet::new();
    let mut in_fence = false;
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            in_fence = !in_fence;
            continue;
        }
        if in_fence || !line.starts_with('#') {
            continue;
        }
        let base = slug(line.trim_start_matches('#'));
        let mut anchor = base.clone();
        let mut n = 0;
        while !seen.insert(anchor.clone()) {
            n += 1;
            anchor = format!("{base}-{n}");
        }
    }
    seen
}

/// The targets of the inline links and images of a line: `[text](target)`.
fn link_targets(line: &str) -> Vec<String> {
    let mut targets = Vec::new();
    let mut rest = line;
    while let Some(at) = rest.find("](") {
        let after = &rest[at + 2..];
        let Some(close) = after.find(')') else { break };
        let target = after[..close].split_whitespace().next().unwrap_or("");
        targets.push(target.to_owned());
        rest = &after[close..];
    }
    targets
}

/// `path` with `.` and `..` resolved, without touching the file system.
fn normalize(path: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for c in path.components() {
        match c {
            Component::ParentDir => {
                out.pop();
            }
            Component::CurDir => {}
            c => out.push(c),
        }
    }
    out
}

/// Every relative link in README.md and docs/ names a file or folder of this repository,
/// and a `#heading` that the Markdown file it points into has.
#[test]
fn relative_links_point_at_existing_files() {
    let mut broken = Vec::new();
    for path in markdown_files() {
        let text = std::fs::read_to_string(&path).expect("readable Markdown");
        let dir = path.parent().expect("a file has a folder");
        for (n, line) in prose_lines(&text).iter().enumerate() {
            for target in link_targets(line) {
                if target.contains("://") || target.starts_with("mailto:") {
                    continue;
                }
                let (file, anchor) = target.split_once('#').unwrap_or((&target, ""));
                let resolved = if file.is_empty() {
                    path.clone()
                } else {
                    normalize(&dir.join(file))
                };
                let at = format!("{}:{} -> {target}", relative(&path), n + 1);
                if !resolved.starts_with(root()) {
                    broken.push(format!("  {at} (outside the repository)"));
                } else if !resolved.exists() {
                    broken.push(format!("  {at} (no such file)"));
                } else if !anchor.is_empty()
                    && resolved.extension().is_some_and(|e| e == "md")
                    && !anchors(&std::fs::read_to_string(&resolved).expect("readable"))
                        .contains(anchor)
                {
                    broken.push(format!("  {at} (no such heading)"));
                }
            }
        }
    }
    assert!(
        broken.is_empty(),
        "broken links in the docs:\n{}",
        broken.join("\n")
    );
}

#[test]
fn slugs_follow_github() {
    assert_eq!(slug(" What can go wrong"), "what-can-go-wrong");
    assert_eq!(
        slug(" Convert: LeRobot v3.0 / v2.1 (`convert`)"),
        "convert-lerobot-v30--v21-convert"
    );
    assert_eq!(
        subcommands(
            "Usage: x\n\nCommands:\n  render  Frames\n          more\n  help    Print\n\nOptions:\n"
        ),
        ["render"]
    );
    assert_eq!(
        link_targets("see [a](docs/a.md#b) and ![p](docs/p.png \"t\")"),
        ["docs/a.md#b", "docs/p.png"]
    );
}
