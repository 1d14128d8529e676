//! `unlock <key>`, `lock` and `key provision <key>`: the command side of
//! [`crate::protocol::access`], which holds the mechanism (timeout, wrong-key back-off).
//! [`AccessState`] is the access control plus its configuration and the key provisioned since
//! boot; the executor asks it whether a protected command may run and extends the unlock when
//! one succeeded.
//!
//! The key in force is the one read from OTP at boot ([`Identity::key`]) or, on a board that
//! booted unprovisioned, the one `key provision` wrote since. Without either, `unlock` answers
//! `ERR 16` and nothing protected can run (see [`crate::protocol::key`]).

use super::{ok_with, Answer};
use crate::protocol::access::{Access, AccessConfig, UnlockOutcome};
use crate::protocol::key::Key;
use crate::protocol::link::{DeviceLink, Identity, KeyWriteError};
use crate::protocol::respond::Response;
use crate::protocol::ErrorCode;

/// Access control and its configuration.
#[derive(Clone, Debug)]
pub struct AccessState {
    access: Access,
    config: AccessConfig,
    /// Written by `key provision` since boot (OTP is read only at boot).
    provisioned: Option<Key>,
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
            provisioned: None,
        }
    }

    /// After a reset: the wrong-key count kept in backup RAM, its windows counted from
    /// `now_ms` ([`Access::restored`]).
    pub fn restore_wrong_keys(&mut self, wrong_keys: u32, now_ms: u64) {
        self.access = Access::restored(&self.config, wrong_keys, now_ms);
    }

    /// Wrong keys since the last correct one (what the service keeps across resets).
    pub fn wrong_keys(&self) -> u32 {
        self.access.wrong_keys()
    }

    /// Whether an unlock is in force at `now_ms` (an expired one is dropped).
    pub fn is_unlocked(&mut self, now_ms: u64) -> bool {
        self.access.is_unlocked(now_ms)
    }

    /// A protected command succeeded: the unlock runs for another timeout from `now_ms`.
    pub fn touch(&mut self, now_ms: u64) {
        self.access.touch(&self.config, now_ms);
    }

    /// The key in force: from OTP at boot, or provisioned since.
    fn key(&self, id: &Identity) -> Option<Key> {
        id.key.or(self.provisioned)
    }

    /// Whether the board has a key (`status`: `key=provisioned`).
    pub fn provisioned(&self, id: &Identity) -> bool {
        self.key(id).is_some()
    }

    /// `key provision <key>`: only while unprovisioned; the board stays locked.
    pub fn provision<D: DeviceLink>(&mut self, id: &Identity, device: &mut D, key: Key) -> Answer {
        if self.provisioned(id) {
            return Err(ErrorCode::WrongState);
        }
        match device.program_key(&key) {
            Ok(()) => {
                self.provisioned = Some(key);
                Ok(ok_with(format_args!("key=provisioned")))
            }
            Err(KeyWriteError::NotBlank) => Err(ErrorCode::WrongState),
            Err(KeyWriteError::Failed) => Err(ErrorCode::FlashError),
        }
    }

    /// `unlock <key>`.
    pub fn unlock(&mut self, id: &Identity, now_ms: u64, given: &Key) -> Answer {
        let key = self.key(id).ok_or(ErrorCode::NoKey)?;
        match self.access.unlock(&self.config, now_ms, &key, given) {
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
    use crate::protocol::commands::testing::{text, MemDevice, ID};

    fn key() -> Key {
        ID.key.unwrap()
    }

    fn wrong_key() -> Key {
        let mut bytes = key().to_bytes();
        bytes[0] ^= 1;
        Key::from_bytes(bytes)
    }

    #[test]
    fn right_key_unlocks_for_the_timeout() {
        let mut a = AccessState::new();
        assert!(!a.is_unlocked(0));
        let answer = text(a.unlock(&ID, 0, &key()).unwrap());
        let timeout_s = AccessConfig::DEFAULT.unlock_timeout_ms / 1000;
        assert_eq!(answer.trim_end(), format!("OK unlocked for_s={timeout_s}"));
        assert!(a.is_unlocked(1));
        assert!(!a.is_unlocked(AccessConfig::DEFAULT.unlock_timeout_ms as u64 + 1));
    }

    #[test]
    fn wrong_key_is_refused_and_leaves_it_locked() {
        let mut a = AccessState::new();
        assert_eq!(
            a.unlock(&ID, 0, &wrong_key()).unwrap_err(),
            ErrorCode::WrongKey
        );
        assert!(!a.is_unlocked(0));
    }

    #[test]
    fn repeated_wrong_keys_are_rate_limited_with_the_wait() {
        let mut a = AccessState::new();
        let mut limited = None;
        for _ in 0..20 {
            if let Ok(r) = a.unlock(&ID, 0, &wrong_key()) {
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
        a.unlock(&ID, 0, &key()).unwrap();
        let timeout_ms = AccessConfig::DEFAULT.unlock_timeout_ms as u64;
        a.touch(timeout_ms - 1);
        assert!(a.is_unlocked(timeout_ms + 10));
        assert_eq!(text(a.lock()).trim_end(), "OK locked");
        assert!(!a.is_unlocked(timeout_ms + 11));
    }

    /// An unprovisioned board refuses `unlock` whatever the key (no default key exists);
    /// `key provision` writes the key once, after which that key unlocks and a second
    /// provisioning is refused without writing.
    #[test]
    fn unprovisioned_board_has_no_key_until_provisioned_once() {
        let blank = Identity { key: None, ..ID };
        let mut a = AccessState::new();
        let mut d = MemDevice::default();
        for given in [key(), wrong_key()] {
            assert_eq!(a.unlock(&blank, 0, &given).unwrap_err(), ErrorCode::NoKey);
        }
        assert!(!a.provisioned(&blank));
        let answer = text(a.provision(&blank, &mut d, key()).unwrap());
        assert_eq!(answer.trim_end(), "OK key=provisioned");
        assert_eq!(d.otp_key, Some(key()));
        assert!(a.provisioned(&blank));
        assert_eq!(
            a.provision(&blank, &mut d, wrong_key()).unwrap_err(),
            ErrorCode::WrongState
        );
        assert_eq!(d.otp_key, Some(key()), "OTP written once");
        assert!(!a.is_unlocked(0), "provisioning does not unlock");
        assert!(a.unlock(&blank, 0, &key()).is_ok());
        assert!(a.is_unlocked(1));
    }

    /// A board whose OTP already holds a key refuses provisioning without writing.
    #[test]
    fn provisioned_board_refuses_a_new_key() {
        let mut a = AccessState::new();
        let mut d = MemDevice::default();
        assert_eq!(
            a.provision(&ID, &mut d, wrong_key()).unwrap_err(),
            ErrorCode::WrongState
        );
        assert_eq!(d.otp_key, None);
    }

    /// A failed OTP write leaves the board unprovisioned.
    #[test]
    fn failed_otp_write_leaves_it_unprovisioned() {
        let blank = Identity { key: None, ..ID };
        let mut a = AccessState::new();
        let mut d = MemDevice {
            fail_store: true,
            ..MemDevice::default()
        };
        assert_eq!(
            a.provision(&blank, &mut d, key()).unwrap_err(),
            ErrorCode::FlashError
        );
        assert!(!a.provisioned(&blank));
    }
}
