//! `rlg-cal console`: the protocol at a terminal, without socat or picocom.
//!
//! A line editor (rustyline: editing, history with Up/Down, Tab completion) in front of the
//! same [`Client`] every other subcommand uses, so each line goes out with its CRC suffix and
//! its one answer is checked; the answer is shown as the board sent it (`OK ...`), an error
//! with its code in words (`ERR 9 (locked): locked (unlock first)`). Completion offers the
//! board's own command names: the grammar of its `help` answer
//! (`get{a|b|coeffs} cal{start<n>[<warmup>]|status|...}`) expanded into word sequences, so the
//! list is the firmware's, never a second copy. Stream frames are counted, not printed.
//!
//! Stdin not a terminal: rustyline reads plain lines (no editing), so a here-document works.

use crate::client::{Client, ClientError};
use crate::link::Link;
use rustyline::completion::{Completer, Pair};
use rustyline::error::ReadlineError;
use rustyline::highlight::Highlighter;
use rustyline::hint::Hinter;
use rustyline::validate::Validator;
use rustyline::{Context, Editor, Helper};

/// The command phrases of the board's `help` grammar: `get{a|b|coeffs}` -> `get a`, `get b`,
/// `get coeffs`; arguments (`<...>`, `[...]`) dropped; the leading `commands:` skipped.
pub fn command_phrases(help: &str) -> Vec<Vec<String>> {
    let mut out = Vec::new();
    for token in help.split_whitespace().filter(|t| !t.ends_with(':')) {
        let head_end = token.find(['{', '<', '[']).unwrap_or(token.len());
        let head = token[..head_end].to_ascii_lowercase();
        if head.is_empty() {
            continue;
        }
        let rest = &token[head_end..];
        match rest.strip_prefix('{').and_then(|r| r.rsplit_once('}')) {
            Some((alternatives, _)) => {
                for alt in split_top_level(alternatives) {
                    let word_end = alt.find(['<', '[']).unwrap_or(alt.len());
                    let word = alt[..word_end].to_ascii_lowercase();
                    let mut phrase = vec![head.clone()];
                    if !word.is_empty() {
                        phrase.push(word);
                    }
                    out.push(phrase);
                }
            }
            None => out.push(vec![head]),
        }
    }
    out
}

/// `a|b<n>[<m>]|c` split at the `|` outside brackets.
fn split_top_level(s: &str) -> Vec<&str> {
    let (mut parts, mut depth, mut start) = (Vec::new(), 0i32, 0);
    for (i, c) in s.char_indices() {
        match c {
            '<' | '[' | '{' => depth += 1,
            '>' | ']' | '}' => depth -= 1,
            '|' if depth == 0 => {
                parts.push(&s[start..i]);
                start = i + 1;
            }
            _ => {}
        }
    }
    parts.push(&s[start..]);
    parts
}

/// Completions of the word being typed at the end of `line`: (its start, candidates).
pub fn complete_words(phrases: &[Vec<String>], line: &str) -> (usize, Vec<String>) {
    let start = line.rfind(' ').map_or(0, |i| i + 1);
    let typed: Vec<String> = line[..start]
        .split_whitespace()
        .map(str::to_ascii_lowercase)
        .collect();
    let partial = line[start..].to_ascii_lowercase();
    let mut candidates: Vec<String> = phrases
        .iter()
        .filter(|p| p.len() > typed.len() && p[..typed.len()] == typed[..])
        .map(|p| &p[typed.len()])
        .filter(|w| w.starts_with(&partial))
        .map(|w| format!("{w} "))
        .collect();
    candidates.dedup();
    candidates.sort();
    candidates.dedup();
    (start, candidates)
}

/// An error answer in words: `ERR <code> (<name of the code>): <the board's text>`.
pub fn describe_error(e: &ClientError) -> String {
    match e {
        ClientError::Device(d) => {
            let name = d
                .kind
                .map_or("unknown code".to_owned(), |k| words(&format!("{k:?}")));
            format!("ERR {} ({name}): {}", d.code, d.text)
        }
        other => other.to_string(),
    }
}

/// `WrongKey` -> `wrong key`.
fn words(camel: &str) -> String {
    let mut out = String::new();
    for c in camel.chars() {
        if c.is_ascii_uppercase() && !out.is_empty() {
            out.push(' ');
        }
        out.push(c.to_ascii_lowercase());
    }
    out
}

struct Commands {
    phrases: Vec<Vec<String>>,
}

impl Completer for Commands {
    type Candidate = Pair;
    fn complete(
        &self,
        line: &str,
        pos: usize,
        _: &Context<'_>,
    ) -> rustyline::Result<(usize, Vec<Pair>)> {
        let (start, words) = complete_words(&self.phrases, &line[..pos]);
        let pairs = words
            .into_iter()
            .map(|w| Pair {
                display: w.trim_end().to_owned(),
                replacement: w,
            })
            .collect();
        Ok((start, pairs))
    }
}

impl Hinter for Commands {
    type Hint = String;
}
impl Highlighter for Commands {}
impl Validator for Commands {}
impl Helper for Commands {}

/// Runs the console until Ctrl-D (or `quit`); a link failure ends it with the error.
pub fn run<L: Link>(client: &mut Client<L>) -> Result<(), ClientError> {
    let id = client.command("id")?;
    let phrases = command_phrases(&client.command("help")?.text);
    let mut editor: Editor<Commands, _> =
        Editor::new().map_err(|e| ClientError::Link(std::io::Error::other(e.to_string())))?;
    editor.set_helper(Some(Commands { phrases }));
    eprintln!(
        "Connected: {}. Tab completes the board's commands, Up/Down recall lines, Ctrl-D quits.",
        id.text
    );
    loop {
        let line = match editor.readline("> ") {
            Ok(line) => line,
            Err(ReadlineError::Interrupted) => continue,
            Err(ReadlineError::Eof) => return Ok(()),
            Err(e) => return Err(ClientError::Link(std::io::Error::other(e.to_string()))),
        };
        let line = line.trim();
        if line.is_empty() {
            continue;
        }
        let _ = editor.add_history_entry(line);
        if matches!(line, "quit" | "exit") {
            return Ok(());
        }
        match client.command(line) {
            Ok(answer) => println!("OK {}", answer.text),
            // The link is gone: nothing more can be said to the board.
            Err(e @ ClientError::Link(_)) => return Err(e),
            Err(e) => println!("{}", describe_error(&e)),
        }
        let frames = client.take_frames().len();
        if frames > 0 {
            println!("({frames} stream frames received, not shown: `stream off` ends the stream)");
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const HELP: &str = "commands: id status get{a|b|coeffs} set{a|b}<rad/s> comp{on|off} \
cal{start<n>[<warmup>]|status|abort|result|accept} stream{on[<n>]|off} unlock<key> lock help";

    #[test]
    fn the_help_grammar_expands_to_phrases() {
        let p = command_phrases(HELP);
        let has = |s: &str| p.iter().any(|x| x.join(" ") == s);
        for s in [
            "id",
            "get coeffs",
            "set b",
            "cal start",
            "cal accept",
            "stream on",
            "unlock",
            "lock",
        ] {
            assert!(has(s), "{s} in {p:?}");
        }
        assert!(!has("commands:"));
    }

    #[test]
    fn completion_goes_word_by_word() {
        let p = command_phrases(HELP);
        assert_eq!(complete_words(&p, "ge"), (0, vec!["get ".to_owned()]));
        assert_eq!(
            complete_words(&p, "cal st"),
            (4, vec!["start ".to_owned(), "status ".to_owned()])
        );
        assert_eq!(
            complete_words(&p, "GET co"),
            (4, vec!["coeffs ".to_owned()])
        );
        assert_eq!(complete_words(&p, "set a "), (6, vec![]));
    }

    #[test]
    fn error_codes_in_words() {
        assert_eq!(words("WrongKey"), "wrong key");
        assert_eq!(words("Locked"), "locked");
    }
}
