//! `unlock <key>` and `lock`: the command side of [`crate::protocol::access`], which holds the
//! mechanism (timeout, wrong-key back-off). [`AccessState`] is the access control plus its
//! configuration; the executor asks it whether a protected command may run and extends the
//! unlock when one succeeded.

use super::{ok_with, Answer};
use crate::protocol::access::{Access, AccessConfig, UnlockOutcome};
use crate::protocol::link::Identity;
use crate::protocol::respond::Response;
use crate::protocol::ErrorCode;

/// Access control and its configuration.
#[derive(Clone, Debug)]
pub struct AccessState {
    access: Access,
    config: AccessConfig,
}

impl Default for AccessState {
    fn default() -> Self {
        Self::new()
    }
}

impl AccessState {
    /// Locked, with [`AccessConfig::DEFAULT`].
    pub fn new() -> Self {
        Self {
            access: Access::new(),
            config: AccessConfig::DEFAULT,
        }
    }

    /// Whether an unlock is in force at `now_ms` (an expired one is dropped).
    pub fn is_unlocked(&mut self, now_ms: u32) -> bool {
        self.access.is_unlocked(now_ms)
    }

    /// A protected command succeeded: the unlock runs for another timeout from `now_ms`.
    pub fn touch(&mut self, now_ms: u32) {
        self.access.touch(&self.config, now_ms);
    }

    /// `unlock <key>`.
    pub fn unlock(&mut self, id: &Identity, now_ms: u32, given: u32) -> Answer {
        match self.access.unlock(&self.config, now_ms, id.key, given) {
            UnlockOutcome::Unlocked => Ok(ok_with(format_args!(
                "unlocked for_s={}",
                self.config.unlock_timeout_ms / 1000
            ))),
            UnlockOutcome::WrongKey => Err(ErrorCode::WrongKey),
            UnlockOutcome::RateLimited { wait_ms } => {
                let mut e = Response::err(ErrorCode::RateLimited);
                e.field(format_args!("wait_ms={wait_ms}"));
                Ok(e)
            }
        }
    }

    /// `lock`.
    pub fn lock(&mut self) -> Response {
        self.access.lock();
        ok_with(format_args!("locked"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::commands::testing::{text, ID};

    #[test]
    fn right_key_unlocks_for_the_timeout() {
        let mut a = AccessState::new();
        assert!(!a.is_unlocked(0));
        let answer = text(a.unlock(&ID, 0, ID.key).unwrap());
        let timeout_s = AccessConfig::DEFAULT.unlock_timeout_ms / 1000;
        assert_eq!(answer.trim_end(), format!("OK unlocked for_s={timeout_s}"));
        assert!(a.is_unlocked(1));
        assert!(!a.is_unlocked(AccessConfig::DEFAULT.unlock_timeout_ms + 1));
    }

    #[test]
    fn wrong_key_is_refused_and_leaves_it_locked() {
        let mut a = AccessState::new();
        assert_eq!(
            a.unlock(&ID, 0, ID.key ^ 1).unwrap_err(),
            ErrorCode::WrongKey
        );
        assert!(!a.is_unlocked(0));
    }

    #[test]
    fn repeated_wrong_keys_are_rate_limited_with_the_wait() {
        let mut a = AccessState::new();
        let mut limited = None;
        for _ in 0..20 {
            if let Ok(r) = a.unlock(&ID, 0, ID.key ^ 1) {
                limited = Some(text(r));
                break;
            }
        }
        let line = limited.expect("back-off after repeated wrong keys");
        assert!(line.starts_with("ERR 14 "), "{line}");
        assert!(line.contains("wait_ms="), "{line}");
        // While limited even the right key is refused.
        assert!(!a.is_unlocked(0));
    }

    #[test]
    fn lock_ends_the_unlock_and_touch_extends_it() {
        let mut a = AccessState::new();
        a.unlock(&ID, 0, ID.key).unwrap();
        let timeout_ms = AccessConfig::DEFAULT.unlock_timeout_ms;
        a.touch(timeout_ms - 1);
        assert!(a.is_unlocked(timeout_ms + 10));
        assert_eq!(text(a.lock()).trim_end(), "OK locked");
        assert!(!a.is_unlocked(timeout_ms + 11));
    }
}
