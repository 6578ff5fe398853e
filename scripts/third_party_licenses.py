"""The licences of the Rust crates compiled into dexjoco-data, as Markdown.

Reads `cargo metadata --format-version 1` on stdin; follows the normal (not dev, not
build) dependencies of the `dexjoco-data` package, outside the workspace; prints a table
(crate, version, licence, repository) and then each distinct licence file text found in
the crates' sources (LICENSE*, LICENCE*, COPYING*, NOTICE*, UNLICENSE), once, with the
crates it belongs to. Used by scripts/package.sh for the release bundle.
"""

import json
import os
import sys

ROOT_PACKAGE = "dexjoco-data"
LICENSE_PREFIXES = ("license", "licence", "copying", "notice", "unlicense")


def compiled_in(meta):
    """Package ids reachable from the root by normal dependencies."""
    nodes = {n["id"]: n for n in meta["resolve"]["nodes"]}
    root = next(p["id"] for p in meta["packages"] if p["name"] == ROOT_PACKAGE)
    seen, todo = set(), [root]
    while todo:
        pid = todo.pop()
        if pid in seen:
            continue
        seen.add(pid)
        for dep in nodes[pid]["deps"]:
            if any(k["kind"] is None for k in dep["dep_kinds"]):
                todo.append(dep["pkg"])
    members = set(meta["workspace_members"])
    return seen - members


def licence_files(manifest_path):
    folder = os.path.dirname(manifest_path)
    found = []
    for name in sorted(os.listdir(folder)):
        path = os.path.join(folder, name)
        if name.lower().startswith(LICENSE_PREFIXES) and os.path.isfile(path):
            with open(path, encoding="utf-8", errors="replace") as f:
                found.append((name, f.read().strip()))
    return found


def main():
    meta = json.load(sys.stdin)
    ids = compiled_in(meta)
    packages = sorted(
        (p for p in meta["packages"] if p["id"] in ids),
        key=lambda p: (p["name"], p["version"]),
    )
    print("# Rust crates compiled into dexjoco-data\n")
    print(f"{len(packages)} crates, as `Cargo.lock` pins them.\n")
    print("| crate | version | licence | repository |")
    print("|---|---|---|---|")
    texts = {}
    for p in packages:
        label = f"{p['name']} {p['version']}"
        print(f"| {p['name']} | {p['version']} | {p.get('license') or p.get('license_file') or '?'} | {p.get('repository') or ''} |")
        for name, text in licence_files(p["manifest_path"]):
            texts.setdefault(text, []).append(f"{label} ({name})")
    print("\n# Licence texts\n")
    print("Each distinct text found in the crates' sources, once, with the crates it comes from.\n")
    for text, owners in texts.items():
        print("---\n")
        print("From: " + ", ".join(owners) + "\n")
        print("```text")
        print(text.replace("```", "'''"))
        print("```\n")


if __name__ == "__main__":
    main()
