//! Access control: commands that change coefficients or flash need an unlock.
//!
//! - `unlock <key>` with the device's calibration key (per board, programmed in OTP; see
//!   `board::app`) unlocks for [`AccessConfig::unlock_timeout_ms`]; any successful protected
//!   command extends it.
//! - The board starts locked at reset, and `lock` locks at once.
//! - Wrong keys are rate-limited: after [`AccessConfig::free_attempts`] wrong keys, each further
//!   attempt must wait a penalty that doubles per wrong key (capped); an attempt during the
//!   penalty is refused without being checked (`ERR 14`), so guessing a 32-bit key over a
//!   serial line takes geological time. A correct key resets the count. A wrong key also locks
//!   a board that was unlocked: whoever types it is not to be trusted with the open session.
//! - Reads never need an unlock.
//! - The wrong-key count survives a reset: the service saves it whenever it changes (backup
//!   RAM on the board) and restores it at boot ([`Access::restored`]), which restarts the
//!   penalty of that count; resetting the board is no way around the back-off.
//!
//! The key itself ([`super::key::Key`], 128 bits) is compared in constant time.
//!
//! Time is a 64-bit monotonic millisecond count passed in by the caller (it never wraps: 584
//! million years), so a deadline is reached exactly when `now >= deadline`, after any uptime;
//! plain logic, testable on the host.

use super::key::Key;

/// Access-control settings (immutable).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AccessConfig {
    /// How long an unlock lasts after the unlock or the last successful protected command, ms.
    pub unlock_timeout_ms: u32,
    /// Wrong keys allowed before penalties start.
    pub free_attempts: u8,
    /// First penalty, doubled per further wrong key, ms.
    pub base_penalty_ms: u32,
    /// Cap of the doubling penalty, ms.
    pub max_penalty_ms: u32,
}

impl AccessConfig {
    /// 5 minutes unlocked; 3 free attempts, then 1 s, 2 s, 4 s ... up to 10 minutes.
    pub const DEFAULT: Self = Self {
        unlock_timeout_ms: 300_000,
        free_attempts: 3,
        base_penalty_ms: 1_000,
        max_penalty_ms: 600_000,
    };
}

/// What an unlock attempt did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UnlockOutcome {
    /// The key matched: unlocked for the timeout, wrong-key count reset.
    Unlocked,
    /// The key did not match: locked, counted, penalty started after the free attempts.
    WrongKey,
    /// Refused unchecked: wait this long.
    RateLimited {
        /// Time left of the penalty, ms.
        wait_ms: u64,
    },
}

/// The lock's state (starts locked).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Access {
    unlocked_until_ms: Option<u64>,
    wrong_keys: u32,
    blocked_until_ms: Option<u64>,
}

/// `now_ms` is at or after `deadline_ms` (monotonic 64-bit milliseconds).
fn reached(now_ms: u64, deadline_ms: u64) -> bool {
    now_ms >= deadline_ms
}

impl Access {
    /// Locked, no wrong keys, no penalty (the state at reset).
    pub const fn new() -> Self {
        Self {
            unlocked_until_ms: None,
            wrong_keys: 0,
            blocked_until_ms: None,
        }
    }

    /// Whether protected commands are allowed now.
    pub fn is_unlocked(&mut self, now_ms: u64) -> bool {
        match self.unlocked_until_ms {
            Some(until) if !reached(now_ms, until) => true,
            Some(_) => {
                self.unlocked_until_ms = None;
                false
            }
            None => false,
        }
    }

    /// A protected command succeeded: the unlock lasts another full timeout.
    pub fn touch(&mut self, config: &AccessConfig, now_ms: u64) {
        if self.is_unlocked(now_ms) {
            self.unlocked_until_ms = Some(now_ms.saturating_add(config.unlock_timeout_ms as u64));
        }
    }

    /// Locks at once (`lock`, or a wrong key).
    pub fn lock(&mut self) {
        self.unlocked_until_ms = None;
    }

    /// Wrong keys since the last correct one.
    pub fn wrong_keys(&self) -> u32 {
        self.wrong_keys
    }

    /// The state after a reset that kept `wrong_keys` (backup RAM, `service::ports::Secrets`):
    /// locked, the count as it was, and, past the free attempts, the penalty of that count
    /// started afresh at `now_ms` (the time left before the reset is unknown; a full penalty
    /// is the safe side). So a reset never shortens a penalty, and repeated resets extend it.
    pub fn restored(config: &AccessConfig, wrong_keys: u32, now_ms: u64) -> Self {
        let mut access = Self::new();
        access.wrong_keys = wrong_keys;
        access.start_penalty(config, now_ms);
        access
    }

    /// Starts the penalty the wrong-key count calls for (none within the free attempts).
    fn start_penalty(&mut self, config: &AccessConfig, now_ms: u64) {
        if self.wrong_keys > config.free_attempts as u32 {
            let doublings = (self.wrong_keys - config.free_attempts as u32 - 1).min(31);
            let penalty = config
                .base_penalty_ms
                .saturating_mul(1u32 << doublings)
                .min(config.max_penalty_ms);
            self.blocked_until_ms = Some(now_ms.saturating_add(penalty as u64));
        }
    }

    /// An unlock attempt with `given` against the device's `key`.
    pub fn unlock(
        &mut self,
        config: &AccessConfig,
        now_ms: u64,
        key: &Key,
        given: &Key,
    ) -> UnlockOutcome {
        if let Some(until) = self.blocked_until_ms {
            if !reached(now_ms, until) {
                return UnlockOutcome::RateLimited {
                    wait_ms: until - now_ms,
                };
            }
            self.blocked_until_ms = None;
        }
        if key.matches(given) {
            self.wrong_keys = 0;
            self.unlocked_until_ms = Some(now_ms.saturating_add(config.unlock_timeout_ms as u64));
            return UnlockOutcome::Unlocked;
        }
        self.lock();
        self.wrong_keys = self.wrong_keys.saturating_add(1);
        self.start_penalty(config, now_ms);
        UnlockOutcome::WrongKey
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const KEY: Key = Key::from_bytes([0x5A; 16]);

    fn wrong(n: u8) -> Key {
        Key::from_bytes([n; 16])
    }
    const C: AccessConfig = AccessConfig::DEFAULT;

    #[test]
    fn starts_locked_unlocks_and_times_out() {
        let mut a = Access::new();
        assert!(!a.is_unlocked(0));
        assert_eq!(a.unlock(&C, 1000, &KEY, &KEY), UnlockOutcome::Unlocked);
        assert!(a.is_unlocked(1000 + C.unlock_timeout_ms as u64 - 1));
        assert!(!a.is_unlocked(1000 + C.unlock_timeout_ms as u64));
    }

    #[test]
    fn activity_extends_and_lock_ends_it() {
        let mut a = Access::new();
        a.unlock(&C, 0, &KEY, &KEY);
        a.touch(&C, 200_000);
        assert!(a.is_unlocked(450_000));
        a.lock();
        assert!(!a.is_unlocked(450_001));
    }

    /// Three free wrong keys, then 1 s, 2 s, 4 s penalties; attempts during a penalty are not
    /// even checked (the right key is refused too); the right key afterwards resets the count.
    #[test]
    fn wrong_keys_are_rate_limited() {
        let mut a = Access::new();
        for t in 0..3 {
            assert_eq!(a.unlock(&C, t, &KEY, &wrong(1)), UnlockOutcome::WrongKey);
        }
        assert_eq!(a.unlock(&C, 10, &KEY, &wrong(2)), UnlockOutcome::WrongKey); // 4th: 1 s penalty
        assert_eq!(
            a.unlock(&C, 500, &KEY, &KEY),
            UnlockOutcome::RateLimited { wait_ms: 510 }
        );
        assert!(!a.is_unlocked(500));
        assert_eq!(a.unlock(&C, 1010, &KEY, &wrong(3)), UnlockOutcome::WrongKey); // 5th: 2 s
        assert_eq!(
            a.unlock(&C, 3000, &KEY, &KEY),
            UnlockOutcome::RateLimited { wait_ms: 10 }
        );
        assert_eq!(a.unlock(&C, 3010, &KEY, &KEY), UnlockOutcome::Unlocked);
        assert_eq!(a.wrong_keys(), 0);
    }

    /// The penalty is capped, and the wrapping clock is handled.
    #[test]
    fn penalty_cap_and_clock_wrap() {
        let mut a = Access::new();
        let mut t = u32::MAX as u64 - 5_000;
        for _ in 0..40 {
            if let UnlockOutcome::RateLimited { wait_ms } = a.unlock(&C, t, &KEY, &wrong(0)) {
                assert!(wait_ms <= C.max_penalty_ms as u64);
                t += wait_ms;
            }
        }
        assert_eq!(
            a.unlock(&C, t + C.max_penalty_ms as u64, &KEY, &KEY),
            UnlockOutcome::Unlocked
        );
    }

    /// A stale unlock stays stale and a penalty ends, however long the board runs: 24.9 days
    /// (2^31 ms) after an unlock nobody used, and across the 32-bit millisecond wrap (49.7 days).
    #[test]
    fn long_uptimes_neither_revive_an_unlock_nor_stretch_a_penalty() {
        let day_ms: u64 = 86_400_000;
        let mut a = Access::new();
        assert_eq!(a.unlock(&C, 1000, &KEY, &KEY), UnlockOutcome::Unlocked);
        for t in [25 * day_ms, 50 * day_ms, (1 << 32) + 1000, (1 << 33) + 500] {
            assert!(
                !Access { ..a }.is_unlocked(t),
                "stale unlock valid at {t} ms"
            );
        }
        // Unlocked just before the 32-bit wrap: lasts its 5 minutes across it, then ends.
        let t0 = (1u64 << 32) - 1000;
        assert_eq!(a.unlock(&C, t0, &KEY, &KEY), UnlockOutcome::Unlocked);
        assert!(a.is_unlocked(t0 + 200_000));
        assert!(!a.is_unlocked(t0 + 400_000));
        // A penalty started before the wrap ends after at most max_penalty_ms.
        let mut b = Access::new();
        for _ in 0..40 {
            let _ = b.unlock(&C, t0, &KEY, &wrong(9));
        }
        let later = t0 + C.max_penalty_ms as u64 + 1;
        assert_eq!(b.unlock(&C, later, &KEY, &KEY), UnlockOutcome::Unlocked);
        // And one started 24.9 days into the uptime is not 24.8 days long.
        let mut c = Access::new();
        let t1 = (1u64 << 31) - 10;
        for _ in 0..40 {
            let _ = c.unlock(&C, t1, &KEY, &wrong(9));
        }
        match c.unlock(&C, t1 + 20, &KEY, &KEY) {
            UnlockOutcome::RateLimited { wait_ms } => assert!(wait_ms <= C.max_penalty_ms as u64),
            other => panic!("{other:?}"),
        }
    }
}
