//! Access control: commands that change coefficients or flash need an unlock.
//!
//! - `unlock <key>` with the device's calibration key (per board, programmed in OTP; see
//!   `board::app`) unlocks for [`AccessConfig::unlock_timeout_ms`]; any successful protected
//!   command extends it.
//! - The board starts locked at reset, and `lock` locks at once. A wrong key locks a board
//!   that was unlocked: whoever types it is not to be trusted with the open session.
//! - Reads never need an unlock.
//!
//! # Wrong keys: a limit on attempts that never keeps the key holder out
//!
//! The threat: anyone on the line may send anything, wrong keys included, at any rate and at
//! any time, and the board may be reset; the key holder must still get in. So the limit is on
//! *when* attempts are checked, never a state that refuses the right key for long:
//!
//! - [`AccessConfig::free_attempts`] wrong keys in a row are checked at once (typing errors);
//! - after them, attempts are checked only inside *windows*: one opens every
//!   [`AccessConfig::window_period_ms`] (counted from the wrong key that used the last free
//!   attempt, or from boot after a reset that kept the count) and stays open
//!   [`AccessConfig::window_open_ms`]. Every attempt inside a window is checked: the right key
//!   unlocks (and ends the windows), a wrong one is counted. An attempt outside is refused
//!   unchecked (`ERR 14`, with the time to the next window) and changes nothing: refusals
//!   neither move nor lengthen the schedule.
//!
//! Whatever else arrives, the right key is therefore admitted at the first window after it is
//! sent: at most one period (10 s) after the key holder's first attempt, and at most one
//! period after a boot. Guessing gets only the attempts that fit in the windows: at 460800
//! baud (about 1150 `unlock` lines a second) under 300 per 10 s, against 2^128 keys. A correct
//! key resets the count.
//!
//! The wrong-key count survives a reset: the service saves it whenever it changes (backup RAM
//! on the board) and restores it at boot ([`Access::restored`]), so resetting the board never
//! buys the free attempts again.
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
    /// Wrong keys in a row checked at once, before attempts are checked only in windows.
    pub free_attempts: u8,
    /// Past the free attempts: a window opens every this long, ms (the longest the key holder
    /// waits).
    pub window_period_ms: u32,
    /// How long a window stays open, ms: every attempt inside it is checked.
    pub window_open_ms: u32,
}

impl AccessConfig {
    /// 5 minutes unlocked; 3 free wrong keys, then a 250 ms window every 10 s.
    pub const DEFAULT: Self = Self {
        unlock_timeout_ms: 300_000,
        free_attempts: 3,
        window_period_ms: 10_000,
        window_open_ms: 250,
    };
}

/// What an unlock attempt did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UnlockOutcome {
    /// The key matched: unlocked for the timeout, wrong-key count reset.
    Unlocked,
    /// The key did not match: locked, counted (the windows start after the free attempts).
    WrongKey,
    /// Outside a window: refused unchecked, nothing changed; the next window opens in this long.
    RateLimited {
        /// Time to the next window, ms.
        wait_ms: u64,
    },
}

/// The lock's state (starts locked).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Access {
    unlocked_until_ms: Option<u64>,
    wrong_keys: u32,
    /// Past the free attempts: windows open at this instant plus every whole period after it.
    windows_from_ms: Option<u64>,
}

/// `now_ms` is at or after `deadline_ms` (monotonic 64-bit milliseconds).
fn reached(now_ms: u64, deadline_ms: u64) -> bool {
    now_ms >= deadline_ms
}

/// Where `now_ms` lies in the window schedule that started at `from_ms`: `None` inside a
/// window, else the time to the next one. Before the first whole period has passed there is no
/// window yet.
fn window_wait(config: &AccessConfig, from_ms: u64, now_ms: u64) -> Option<u64> {
    let period = u64::from(config.window_period_ms.max(1));
    let since = now_ms.saturating_sub(from_ms);
    if since < period {
        return Some(period.saturating_sub(since));
    }
    let into = since.checked_rem(period).unwrap_or(0);
    (into >= u64::from(config.window_open_ms)).then(|| period.saturating_sub(into))
}

impl Access {
    /// Locked, no wrong keys, no windows (the state at reset).
    pub const fn new() -> Self {
        Self {
            unlocked_until_ms: None,
            wrong_keys: 0,
            windows_from_ms: None,
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
    /// locked, the count as it was, and, past the free attempts, the windows counted from
    /// `now_ms` (the boot): the first opens one period after it. A reset neither gives the free
    /// attempts back nor keeps the key holder out longer than one period.
    pub fn restored(config: &AccessConfig, wrong_keys: u32, now_ms: u64) -> Self {
        Self {
            wrong_keys,
            windows_from_ms: (wrong_keys >= u32::from(config.free_attempts)).then_some(now_ms),
            ..Self::new()
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
        if let Some(from) = self.windows_from_ms {
            if let Some(wait_ms) = window_wait(config, from, now_ms) {
                return UnlockOutcome::RateLimited { wait_ms };
            }
        }
        if key.matches(given) {
            self.wrong_keys = 0;
            self.windows_from_ms = None;
            self.unlocked_until_ms = Some(now_ms.saturating_add(config.unlock_timeout_ms as u64));
            return UnlockOutcome::Unlocked;
        }
        self.lock();
        self.wrong_keys = self.wrong_keys.saturating_add(1);
        if self.windows_from_ms.is_none() && self.wrong_keys >= u32::from(config.free_attempts) {
            self.windows_from_ms = Some(now_ms);
        }
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

    /// Three free wrong keys, then attempts are checked only in the windows: outside, the
    /// right key too is refused unchecked with the time to the next window, and the refusal
    /// changes nothing; inside, a wrong key is counted and the right one unlocks and resets.
    #[test]
    fn past_the_free_attempts_keys_are_checked_only_in_windows() {
        let mut a = Access::new();
        for t in [0, 1, 2] {
            assert_eq!(a.unlock(&C, t, &KEY, &wrong(1)), UnlockOutcome::WrongKey);
        }
        // The third wrong key (at 2 ms) starts the schedule: windows at 10.002 s, 20.002 s, ...
        assert_eq!(
            a.unlock(&C, 500, &KEY, &KEY),
            UnlockOutcome::RateLimited { wait_ms: 9_502 }
        );
        let before = a;
        for t in [501, 3_000, 10_001] {
            assert!(matches!(
                a.unlock(&C, t, &KEY, &wrong(2)),
                UnlockOutcome::RateLimited { .. }
            ));
        }
        assert_eq!(a, before, "refusals change nothing");
        assert!(!a.is_unlocked(10_001));
        assert_eq!(
            a.unlock(&C, 10_002, &KEY, &wrong(2)),
            UnlockOutcome::WrongKey
        );
        assert_eq!(
            a.unlock(&C, 10_100, &KEY, &wrong(2)),
            UnlockOutcome::WrongKey
        );
        assert_eq!(a.wrong_keys(), 5);
        assert_eq!(
            a.unlock(&C, 10_252, &KEY, &KEY),
            UnlockOutcome::RateLimited { wait_ms: 9_750 }
        );
        assert_eq!(
            a.unlock(&C, 20_002 + 249, &KEY, &KEY),
            UnlockOutcome::Unlocked
        );
        assert_eq!(a.wrong_keys(), 0);
        // The count starts again: three free wrong keys.
        for t in [30_000, 30_001, 30_002] {
            assert_eq!(a.unlock(&C, t, &KEY, &wrong(4)), UnlockOutcome::WrongKey);
        }
        assert!(matches!(
            a.unlock(&C, 30_003, &KEY, &KEY),
            UnlockOutcome::RateLimited { .. }
        ));
    }

    /// After a reset that kept the count the first window opens one period after boot; the
    /// free attempts do not come back, and repeated resets never keep the key holder out for
    /// more than a period after the last one.
    #[test]
    fn a_reset_keeps_the_count_and_opens_a_window_one_period_after_boot() {
        let a = Access::restored(&C, 2, 50);
        let mut b = a;
        assert_eq!(b.unlock(&C, 60, &KEY, &wrong(1)), UnlockOutcome::WrongKey);
        assert!(matches!(
            b.unlock(&C, 61, &KEY, &KEY),
            UnlockOutcome::RateLimited { .. }
        ));
        for boot_ms in [0, 1_100, 7_777] {
            let mut r = Access::restored(&C, 40, boot_ms);
            assert_eq!(r.wrong_keys(), 40);
            assert_eq!(
                r.unlock(&C, boot_ms, &KEY, &wrong(1)),
                UnlockOutcome::RateLimited { wait_ms: 10_000 }
            );
            assert_eq!(
                r.unlock(&C, boot_ms + 10_000, &KEY, &KEY),
                UnlockOutcome::Unlocked
            );
        }
    }

    /// A stale unlock stays stale and the windows keep their period, however long the board
    /// runs: 24.9 days (2^31 ms) after an unlock nobody used, and across the 32-bit millisecond
    /// wrap (49.7 days).
    #[test]
    fn long_uptimes_neither_revive_an_unlock_nor_stretch_the_windows() {
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
        // Windows started before the wrap, and 24.9 days into the uptime, still come every 10 s.
        for start in [t0, (1u64 << 31) - 10, u64::MAX - 100_000] {
            let mut b = Access::new();
            for _ in 0..40 {
                let _ = b.unlock(&C, start, &KEY, &wrong(9));
            }
            match b.unlock(&C, start + 20, &KEY, &KEY) {
                UnlockOutcome::RateLimited { wait_ms } => assert_eq!(wait_ms, 9_980),
                other => panic!("{other:?}"),
            }
            assert_eq!(
                b.unlock(&C, start + 10_000, &KEY, &KEY),
                UnlockOutcome::Unlocked
            );
        }
    }

    /// Wrong keys keep coming, one every 7 ms and one in the very millisecond before each of
    /// the key holder's attempts: the key holder, trying at any instant and again when ERR 14
    /// says, is in within one window period (10 s) of his first try. The bound is the rule's;
    /// the longest wait measured is close to it (above 9 s), since the flood keeps the windows.
    #[test]
    fn the_key_holder_gets_in_within_a_period_while_wrong_keys_keep_coming() {
        let period_ms = 10_000u64;
        let mut longest_ms = 0;
        for start_ms in (1..600_000u64).step_by(13_001) {
            let mut a = Access::new();
            let mut owner_at = start_ms;
            let mut t = 0u64;
            let admitted_ms = loop {
                assert!(
                    t < start_ms + 3_600_000,
                    "kept out for an hour from {start_ms} ms"
                );
                if t.is_multiple_of(7) || t == owner_at {
                    let _ = a.unlock(&C, t, &KEY, &wrong(3));
                }
                if t == owner_at {
                    match a.unlock(&C, t, &KEY, &KEY) {
                        UnlockOutcome::Unlocked => break t,
                        UnlockOutcome::RateLimited { wait_ms } => owner_at = t + wait_ms,
                        UnlockOutcome::WrongKey => panic!("the right key counted as wrong"),
                    }
                }
                t += 1;
            };
            let waited_ms = admitted_ms - start_ms;
            assert!(waited_ms <= period_ms, "from {start_ms} ms: {waited_ms} ms");
            longest_ms = longest_ms.max(waited_ms);
        }
        assert!(longest_ms > 9_000, "longest wait {longest_ms} ms");
    }
}
