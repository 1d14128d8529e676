//! The documents a newcomer reads hold together: every relative link in `README.md` and
//! `docs/*.md` reaches a file of the repository (and, for a `file.md#anchor` link, a heading
//! of that file), the README stays a short entry point (at most 200 lines) that links every
//! document, and the README's test command is the one CI runs.
//!
//! Anchors follow GitHub's rule for headings: lower case; letters, digits, `-` and `_` kept,
//! spaces become `-`, everything else (backticks, punctuation) dropped; a repeated heading
//! gets `-1`, `-2`, ... Headings and links inside fenced code blocks are not markdown and are
//! skipped, as are inline code spans.

use std::collections::HashSet;
use std::path::{Component, Path, PathBuf};

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

/// `README.md` and every `docs/*.md`, as paths relative to the root.
fn documents() -> Vec<PathBuf> {
    let mut docs = vec![PathBuf::from("README.md")];
    let mut in_docs: Vec<PathBuf> = std::fs::read_dir(Path::new(ROOT).join("docs"))
        .expect("docs/")
        .map(|e| e.expect("entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .map(|p| p.strip_prefix(ROOT).unwrap().to_path_buf())
        .collect();
    in_docs.sort();
    docs.extend(in_docs);
    docs
}

/// The lines outside fenced code blocks, with their line numbers (1-based).
fn prose(text: &str) -> Vec<(usize, &str)> {
    let mut fenced = false;
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
            continue;
        }
        if !fenced {
            out.push((i + 1, line));
        }
    }
    out
}

/// The line without its inline code spans.
fn without_code(line: &str) -> String {
    line.split('`')
        .enumerate()
        .filter(|(i, _)| i % 2 == 0)
        .map(|(_, s)| s)
        .collect()
}

/// GitHub's anchor of a heading's text.
fn slug(heading: &str) -> String {
    heading
        .trim()
        .chars()
        .filter_map(|c| match c {
            ' ' => Some('-'),
            '-' | '_' => Some(c),
            c if c.is_alphanumeric() => Some(c.to_ascii_lowercase()),
            _ => None,
        })
        .collect()
}

/// The anchors of a markdown file's headings.
fn anchors(text: &str) -> HashSet<String> {
    let mut seen = HashSet::new();
    for (_, line) in prose(text) {
        let hashes = line.chars().take_while(|&c| c == '#').count();
        if hashes == 0 || !line[hashes..].starts_with(' ') {
            continue;
        }
        let base = slug(&line[hashes..]);
        let mut anchor = base.clone();
        let mut n = 0;
        while !seen.insert(anchor.clone()) {
            n += 1;
            anchor = format!("{base}-{n}");
        }
    }
    seen
}

/// The targets of `[text](target)` and `![alt](target)` links, with their line numbers.
fn links(text: &str) -> Vec<(usize, String)> {
    let mut out = Vec::new();
    for (n, line) in prose(text) {
        let line = without_code(line);
        let mut rest = line.as_str();
        while let Some(at) = rest.find("](") {
            let after = &rest[at + 2..];
            let Some(end) = after.find(')') else { break };
            out.push((n, after[..end].trim().to_owned()));
            rest = &after[end + 1..];
        }
    }
    out
}

/// `path` with `.` and `..` resolved lexically; `None` if it climbs above its start.
fn normalise(path: &Path) -> Option<PathBuf> {
    let mut out = PathBuf::new();
    for part in path.components() {
        match part {
            Component::CurDir => {}
            Component::ParentDir => {
                if !out.pop() {
                    return None;
                }
            }
            Component::Normal(p) => out.push(p),
            Component::RootDir | Component::Prefix(_) => return None,
        }
    }
    Some(out)
}

#[test]
fn every_relative_link_reaches_a_file_and_heading_of_the_repository() {
    let mut checked = 0;
    let mut broken = Vec::new();
    for doc in documents() {
        let text = std::fs::read_to_string(Path::new(ROOT).join(&doc)).expect("readable");
        let dir = doc.parent().unwrap_or(Path::new(""));
        for (line, target) in links(&text) {
            if target.contains("://") || target.starts_with("mailto:") {
                continue;
            }
            let (file, anchor) = match target.split_once('#') {
                Some((f, a)) => (f, Some(a)),
                None => (target.as_str(), None),
            };
            let where_ = format!("{}:{line}: {target}", doc.display());
            let resolved = if file.is_empty() {
                Some(doc.clone())
            } else {
                normalise(&dir.join(file))
            };
            let Some(resolved) = resolved else {
                broken.push(format!("{where_} (leaves the repository)"));
                continue;
            };
            let full = Path::new(ROOT).join(&resolved);
            if !full.exists() {
                broken.push(format!("{where_} (no such file)"));
                continue;
            }
            if let Some(anchor) = anchor {
                let is_md = resolved.extension().is_some_and(|e| e == "md");
                let target_text = std::fs::read_to_string(&full).unwrap_or_default();
                if !is_md || !anchors(&target_text).contains(anchor) {
                    broken.push(format!("{where_} (no heading with that anchor)"));
                    continue;
                }
            }
            checked += 1;
        }
    }
    assert!(broken.is_empty(), "broken links:\n{}", broken.join("\n"));
    // The documents hold some eighty relative links; far fewer means the scan is broken.
    assert!(
        checked >= 60,
        "only {checked} links found: is the scan broken?"
    );
}

/// A newcomer starts at the README: every document of `docs/` is one link away.
#[test]
fn the_readme_links_every_document() {
    let readme = std::fs::read_to_string(Path::new(ROOT).join("README.md")).expect("README.md");
    let linked: HashSet<PathBuf> = links(&readme)
        .into_iter()
        .map(|(_, t)| PathBuf::from(t.split('#').next().unwrap()))
        .collect();
    for doc in documents().into_iter().skip(1) {
        assert!(
            linked.contains(&doc),
            "README.md does not link {}",
            doc.display()
        );
    }
}

#[test]
fn the_readme_is_at_most_200_lines() {
    let text = std::fs::read_to_string(Path::new(ROOT).join("README.md")).expect("README.md");
    let lines = text.lines().count();
    assert!(lines <= 200, "README.md has {lines} lines");
}

/// The README's "The two commands": the main job and the tests, exactly; CI runs the second.
#[test]
fn ci_runs_the_readmes_test_command() {
    let readme = std::fs::read_to_string(Path::new(ROOT).join("README.md")).expect("README.md");
    let section = readme
        .split("\n## The two commands\n")
        .nth(1)
        .expect("a section \"## The two commands\"");
    let block = section
        .split("```")
        .nth(1)
        .expect("a code block in \"The two commands\"");
    let commands: Vec<&str> = block
        .lines()
        .skip(1) // the fence's language tag
        .map(|l| l.split('#').next().unwrap().trim())
        .filter(|l| !l.is_empty())
        .collect();
    assert_eq!(
        commands,
        ["cargo run --release -p rlg-sim -- sweep", "cargo test"],
        "the README's two commands"
    );
    let ci = std::fs::read_to_string(Path::new(ROOT).join(".ci/run")).expect(".ci/run");
    assert!(
        ci.lines().any(|l| l.trim() == commands[1]),
        ".ci/run does not run the README's test command `{}`",
        commands[1]
    );
}

#[test]
fn slugs_follow_githubs_rule() {
    assert_eq!(slug(" The answers' fields"), "the-answers-fields");
    assert_eq!(
        slug(" Corrupted commands: CRC or confirmation"),
        "corrupted-commands-crc-or-confirmation"
    );
    assert_eq!(
        slug(" `dither`: the dither drive alone"),
        "dither-the-dither-drive-alone"
    );
    assert_eq!(
        anchors("# A\n## A\n```\n# A\n```\n"),
        HashSet::from(["a".to_owned(), "a-1".to_owned()])
    );
    assert_eq!(
        links("see [x](a.md#b) and `[y](c.md)`, ![z](f.svg)\n```\n[w](d.md)\n```"),
        [(1, "a.md#b".to_owned()), (1, "f.svg".to_owned())]
    );
}
