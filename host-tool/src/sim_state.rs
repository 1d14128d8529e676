//! The `--sim` board's state file: what lasts from one `rlg-cal --sim` call to the next.
//!
//! A real board keeps its flash when switched off and its settings in RAM while it runs; the
//! simulated board lives only as long as one call. With a state file each call is a reset of
//! the same board: the flash contents (so `store` in one call and `reload` in the next find the
//! record) and the boot count come back, and so do the settings in force that a board keeps
//! while powered: a, b, compensation on/off, the dither amplitude setpoint and noise depth. Not
//! kept: the unlock (a reset locks), a calibration run, tracking, the stream.
//!
//! The settings are read and restored through the protocol (the board's own `get`, `status`,
//! `dither status` answers and its `set`, `comp`, `dither` commands, unlocked with the simulated
//! board's key and locked again), so no second copy of the firmware's state handling exists;
//! a setting equal to what the board booted with is not sent again, so the coefficient source
//! (`coeffs=flash:...`) stays what the flash says when nothing was changed.
//!
//! Format: a text header of `key=value` lines, a blank line, then the raw flash image. Written
//! to a new temporary file beside it and renamed over it, so an interrupted write leaves the
//! old state. The temporary file is created exclusively (`O_EXCL`: never through a file or a
//! symlink someone planted) under a name with the process id and the clock in it, mode 0600.

use crate::client::{Client, ClientError};
use crate::link::Link;
use std::io::{self, Write};
use std::path::Path;

const MAGIC: &str = "rlg-cal sim-board state v1";

/// What the state file holds.
#[derive(Clone, Debug, PartialEq)]
pub struct SimState {
    /// Boots so far (the next boot is this one).
    pub boot_count: u32,
    /// The settings in force: protocol field name -> value as the board printed it.
    pub settings: Vec<(String, String)>,
    /// The flash image (both calibration sectors).
    pub flash: Vec<u8>,
}

/// Reads a state file; `None` if it does not exist yet.
pub fn load(path: &Path) -> io::Result<Option<SimState>> {
    let bytes = match std::fs::read(path) {
        Ok(b) => b,
        Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(e),
    };
    let bad = |why: &str| {
        io::Error::new(
            io::ErrorKind::InvalidData,
            format!("{}: {why}", path.display()),
        )
    };
    let split = bytes
        .windows(2)
        .position(|w| w == b"\n\n")
        .ok_or_else(|| bad("no header"))?;
    let header = std::str::from_utf8(&bytes[..split]).map_err(|_| bad("header not text"))?;
    let mut lines = header.lines();
    if lines.next() != Some(MAGIC) {
        return Err(bad("not an rlg-cal sim-board state file"));
    }
    let mut state = SimState {
        boot_count: 0,
        settings: Vec::new(),
        flash: bytes[split + 2..].to_vec(),
    };
    for line in lines {
        let (key, value) = line
            .split_once('=')
            .ok_or_else(|| bad("header line without ="))?;
        if key == "boot_count" {
            state.boot_count = value.parse().map_err(|_| bad("bad boot_count"))?;
        } else {
            state.settings.push((key.to_owned(), value.to_owned()));
        }
    }
    Ok(Some(state))
}

/// A new file beside `path`, created exclusively (it did not exist: no planted file or symlink
/// is followed), and its name.
fn create_temporary(path: &Path) -> io::Result<(std::fs::File, std::path::PathBuf)> {
    use std::os::unix::fs::OpenOptionsExt;
    let stamp = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos());
    let mut last = io::Error::new(io::ErrorKind::AlreadyExists, "no free temporary name");
    for attempt in 0..16u32 {
        let mut name = path.as_os_str().to_owned();
        name.push(format!(".{}.{stamp:x}.{attempt}.tmp", std::process::id()));
        let tmp = std::path::PathBuf::from(name);
        match std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .mode(0o600)
            .open(&tmp)
        {
            Ok(file) => return Ok((file, tmp)),
            Err(e) if e.kind() == io::ErrorKind::AlreadyExists => last = e,
            Err(e) => return Err(e),
        }
    }
    Err(last)
}

/// Writes a state file (atomically: a new temporary file renamed over it).
pub fn save(path: &Path, state: &SimState) -> io::Result<()> {
    let (file, tmp) = create_temporary(path)?;
    let written = (|| {
        let mut f = io::BufWriter::new(file);
        writeln!(f, "{MAGIC}")?;
        writeln!(f, "boot_count={}", state.boot_count)?;
        for (k, v) in &state.settings {
            writeln!(f, "{k}={v}")?;
        }
        writeln!(f)?;
        f.write_all(&state.flash)?;
        f.into_inner().map_err(|e| e.into_error())?.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if written.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    written
}

/// The boot count after one more boot: saturating, a counter that never wraps.
pub fn next_boot(boot_count: u32) -> u32 {
    boot_count.saturating_add(1)
}

/// The settings kept, each: (name in the state file, the command that reads it, its field, the
/// command that sets it, before the value).
const SETTINGS: [(&str, &str, &str, &str); 5] = [
    ("a", "get coeffs", "a", "set a"),
    ("b", "get coeffs", "b", "set b"),
    ("comp", "status", "comp", "comp"),
    (
        "dither_amp_arcsec",
        "dither status",
        "setpoint_arcsec",
        "dither amp",
    ),
    (
        "dither_noise_pct",
        "dither status",
        "noise_pct",
        "dither noise",
    ),
];

/// The board's settings in force, read through the protocol.
pub fn read_settings<L: Link>(
    client: &mut Client<L>,
) -> Result<Vec<(String, String)>, ClientError> {
    let mut out = Vec::new();
    let mut answers: Vec<(&str, crate::client::Answer)> = Vec::new();
    for (name, query, field, _) in SETTINGS {
        if !answers.iter().any(|(q, _)| *q == query) {
            answers.push((query, client.command(query)?));
        }
        let answer = &answers.iter().find(|(q, _)| *q == query).expect("asked").1;
        if let Some(value) = answer.field(field) {
            out.push((name.to_owned(), value.to_owned()));
        }
    }
    Ok(out)
}

/// Brings the board's settings to `saved` (unlocked with `key`, locked again), sending only
/// those that differ from what it has now.
pub fn restore_settings<L: Link>(
    client: &mut Client<L>,
    saved: &[(String, String)],
    key: &str,
) -> Result<(), ClientError> {
    let now = read_settings(client)?;
    let changes: Vec<String> = SETTINGS
        .iter()
        .filter_map(|(name, _, _, set)| {
            let want = saved.iter().find(|(k, _)| k == name)?;
            let have = now.iter().find(|(k, _)| k == name);
            (have.map(|h| &h.1) != Some(&want.1)).then(|| format!("{set} {}", want.1))
        })
        .collect();
    if changes.is_empty() {
        return Ok(());
    }
    client.command(&format!("unlock {key}"))?;
    for change in &changes {
        client.command(change)?;
    }
    client.command("lock")?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> std::path::PathBuf {
        std::env::temp_dir().join(format!("rlg-sim-state-{}-{name}", std::process::id()))
    }

    /// What is saved is loaded back byte for byte; no file is no state; a file that is not a
    /// state file is refused with its path in the error (nothing is overwritten by loading).
    #[test]
    fn save_load_round_trip_and_refusals() {
        let path = scratch("round");
        let state = SimState {
            boot_count: 7,
            settings: vec![("a".into(), "12.5".into()), ("comp".into(), "on".into())],
            flash: (0..=255u8).cycle().take(4096).collect(),
        };
        save(&path, &state).unwrap();
        assert_eq!(load(&path).unwrap(), Some(state));
        assert_eq!(load(&scratch("missing")).unwrap(), None);
        std::fs::write(&path, b"something else\n\nbytes").unwrap();
        let e = load(&path).unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::InvalidData);
        assert!(
            e.to_string()
                .contains("not an rlg-cal sim-board state file"),
            "{e}"
        );
        assert_eq!(std::fs::read(&path).unwrap(), b"something else\n\nbytes");
        std::fs::remove_file(&path).unwrap();
    }

    /// Saving never writes through a file planted at a predictable name: a symlink at
    /// `<path>.tmp` to another file leaves that file as it was.
    #[test]
    fn saving_does_not_follow_a_planted_symlink() {
        let path = scratch("planted");
        let victim = scratch("victim");
        std::fs::write(&victim, b"precious").unwrap();
        let planted = std::path::PathBuf::from(format!("{}.tmp", path.display()));
        let _ = std::fs::remove_file(&planted);
        std::os::unix::fs::symlink(&victim, &planted).unwrap();
        let state = SimState {
            boot_count: 1,
            settings: Vec::new(),
            flash: vec![0xFF; 64],
        };
        save(&path, &state).unwrap();
        assert_eq!(std::fs::read(&victim).unwrap(), b"precious");
        assert_eq!(load(&path).unwrap(), Some(state));
        for p in [&path, &victim, &planted] {
            let _ = std::fs::remove_file(p);
        }
    }
}
