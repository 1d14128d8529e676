//! Results for people and for scripts: every answer as `key=value` pairs, printed one a line,
//! or as one JSON object per command (`--json`).
//!
//! The board's answers are mostly `key=value` words already; a few start with a bare word
//! (`stored seq=1 readout=resynchronised`, `unlocked for_s=300`, `locked`) and a refusal's reason
//! has words after its code (`reason=1 mean rate inside the dynamic dead band`). The rule that
//! turns any answer into pairs, with nothing dropped:
//! - bare words before the first `key=value` are the `result`;
//! - a word ending in `:` names the rest of the answer (`commands: id status ...`);
//! - bare words after a `key=value` continue its value (the reason's words).
//!
//! The firmware's answers are left as they are (the protocol is typed by people at a terminal);
//! the host tool shapes them.

use serde_json::{Map, Value};

/// The pairs of an answer's text, in order.
pub fn fields(text: &str) -> Vec<(String, String)> {
    let mut out: Vec<(String, String)> = Vec::new();
    let mut words = text.split(' ').filter(|w| !w.is_empty()).peekable();
    while let Some(word) = words.next() {
        if let Some(key) = word.strip_suffix(':').filter(|k| !k.contains('=')) {
            let rest: Vec<&str> = words.by_ref().collect();
            out.push((key.to_owned(), rest.join(" ")));
        } else if let Some((key, value)) = word.split_once('=') {
            out.push((key.to_owned(), value.to_owned()));
        } else if let Some((_, value)) = out.last_mut() {
            value.push(' ');
            value.push_str(word);
        } else {
            out.push(("result".to_owned(), word.to_owned()));
        }
    }
    out
}

/// `key=value`, one a line.
pub fn key_value_lines(fields: &[(String, String)]) -> String {
    fields
        .iter()
        .map(|(k, v)| format!("{k}={v}"))
        .collect::<Vec<_>>()
        .join("\n")
}

/// A JSON value for a field: a number when the text is one (finite), else the text.
fn json_value(text: &str) -> Value {
    text.parse::<f64>()
        .ok()
        .filter(|v| v.is_finite() && !text.starts_with('+'))
        .and_then(serde_json::Number::from_f64)
        .map(|n| {
            // Integers stay integers (sequence numbers, counts).
            text.parse::<i64>().map_or(Value::Number(n), Value::from)
        })
        .unwrap_or_else(|| Value::String(text.to_owned()))
}

/// The fields as one JSON object (a repeated key keeps its last value).
pub fn json_object(fields: &[(String, String)]) -> Value {
    let mut map = Map::new();
    for (k, v) in fields {
        map.insert(k.clone(), json_value(v));
    }
    Value::Object(map)
}

/// How results are printed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// `key=value` lines.
    KeyValue,
    /// One JSON object per command, on one line.
    Json,
}

impl Format {
    /// One command's result: `key=value` lines, or one JSON object whose members are the
    /// fields, plus `sections` as nested objects (e.g. `calibrate`'s `fit`, `accept`, `store`).
    pub fn render(
        &self,
        fields: &[(String, String)],
        sections: &[(&str, Vec<(String, String)>)],
    ) -> String {
        match self {
            Self::KeyValue => {
                let mut lines: Vec<String> = Vec::new();
                if !fields.is_empty() {
                    lines.push(key_value_lines(fields));
                }
                for (name, section) in sections {
                    let prefixed: Vec<(String, String)> = section
                        .iter()
                        .map(|(k, v)| (format!("{name}.{k}"), v.clone()))
                        .collect();
                    lines.push(key_value_lines(&prefixed));
                }
                lines.join("\n")
            }
            Self::Json => {
                let mut object = json_object(fields);
                if let Value::Object(map) = &mut object {
                    for (name, section) in sections {
                        map.insert((*name).to_owned(), json_object(section));
                    }
                }
                object.to_string()
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pairs(text: &str) -> Vec<(String, String)> {
        fields(text)
    }

    fn p(k: &str, v: &str) -> (String, String) {
        (k.to_owned(), v.to_owned())
    }

    /// The answers that were not `key=value`, and the ones that were.
    #[test]
    fn every_answer_becomes_pairs() {
        assert_eq!(
            pairs("stored seq=1 readout=resynchronised"),
            [
                p("result", "stored"),
                p("seq", "1"),
                p("readout", "resynchronised")
            ]
        );
        assert_eq!(pairs("locked"), [p("result", "locked")]);
        assert_eq!(
            pairs("cal=refused reason=1 mean rate inside the dynamic dead band"),
            [
                p("cal", "refused"),
                p("reason", "1 mean rate inside the dynamic dead band")
            ]
        );
        assert_eq!(
            pairs("commands: id status get{a|b|coeffs}"),
            [p("commands", "id status get{a|b|coeffs}")]
        );
        assert_eq!(pairs("a=1.5 b=-2"), [p("a", "1.5"), p("b", "-2")]);
    }

    #[test]
    fn json_has_numbers_as_numbers() {
        let f = pairs("stored seq=1 a=344.12344 readout=resynchronised nan=NaN");
        let json = Format::Json.render(&f, &[("fit", pairs("cond=1.005"))]);
        let v: Value = serde_json::from_str(&json).unwrap();
        assert_eq!(v["result"], "stored");
        assert_eq!(v["seq"], 1);
        assert_eq!(v["a"], 344.12344);
        assert_eq!(v["nan"], "NaN");
        assert_eq!(v["fit"]["cond"], 1.005);
        assert!(!json.contains('\n'));
        assert_eq!(
            Format::KeyValue.render(&f[..2], &[("fit", pairs("cond=1.005"))]),
            "result=stored\nseq=1\nfit.cond=1.005"
        );
    }
}
