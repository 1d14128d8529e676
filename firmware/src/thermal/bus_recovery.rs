//! I2C bus clear (NXP UM10204 3.1.16): a slave that was sending when the master stopped (an MCU
//! reset mid-byte) keeps SDA low and waits for clocks that never come; the master frees it by
//! clocking SCL, up to nine times, until SDA is released, then ends with a STOP.
//!
//! The sequence is plain logic over embedded-hal 1.0's pin traits (`OutputPin` + `InputPin`
//! for each open-drain line: set high = release, set low = pull down, read = the line's level)
//! and a `DelayNs` for the half period, so the host tests below drive it against a simulated
//! slave and the board (`board::i2c`) runs it on PB6/PB7 in GPIO mode.
//!
//! **The sequence** ([`recover`]):
//! 1. Release both lines, wait a half period; SCL must read high within
//!    [`RecoveryTiming::scl_wait_ns`] (a slave may stretch the clock, nothing stretches for
//!    ever): if not, [`Recovery::SclHeldLow`] and nothing more is driven.
//! 2. While SDA reads low (sampled with SCL high, where a slave's data bit is valid): one clock
//!    pulse (SCL low for a half period, released, high for a half period). A transmitting slave
//!    shifts one bit per pulse; at its byte's end it reads the released SDA as a NACK and lets
//!    go. Nine pulses cover the worst case (eight data bits and the acknowledge slot); SDA still
//!    low after nine is [`Recovery::SdaStuck`] (a short to ground, a dead part).
//! 3. A START and a STOP: SDA low with SCL high, SCL low, SCL high, SDA high. The START resets
//!    any slave that released SDA for a `1` bit rather than at its byte's end (every slave
//!    recognises a START at any time), so it cannot drive the STOP's bit; the STOP leaves the
//!    bus idle. SDA must read high after it, or the outcome is `SdaStuck`.
//!
//! The START/STOP runs also when the bus was free at once: it costs 20 us, and the same four
//! edges (SDA low, SCL low, SCL high, SDA high) are the workaround of the STM32F405 erratum
//! "I2C analog filter may provide wrong value, locking BUSY flag and preventing master mode
//! entry" (ES0182): each line's analog filter in the I/O is updated only by a transition on it.
//!
//! **Time** is bounded: 2k + 5 half periods for a slave freed after k pulses (at 100 kHz 25 us
//! on a free bus, 115 us after nine pulses), 19 (95 us) when SDA stays low, 1 half period and
//! [`RecoveryTiming::scl_wait_ns`] (105 us) when SCL stays low; a slave that stretches the clock
//! adds up to `scl_wait_ns` to each of at most ten releases (1 ms more). The tests below check
//! each of these figures on the simulated bus.

use embedded_hal::delay::DelayNs;
use embedded_hal::digital::{InputPin, OutputPin};

/// At most this many clock pulses while SDA is low (UM10204 3.1.16: eight data bits and the
/// acknowledge slot).
pub const MAX_CLOCKS: u8 = 9;

/// The sequence's timing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RecoveryTiming {
    /// Half of one SCL period, ns (5000: 100 kHz, standard mode, which every part accepts).
    pub half_period_ns: u32,
    /// How long a released SCL may stay low (a slave stretching the clock) before the line
    /// counts as held, ns.
    pub scl_wait_ns: u32,
    /// The step of that wait, ns.
    pub scl_poll_ns: u32,
}

impl RecoveryTiming {
    /// 100 kHz, SCL released within 100 us (TMP117 does not stretch; 100 us is ten of its
    /// 400 kHz bytes' bits), polled every microsecond.
    pub const STANDARD: Self = Self {
        half_period_ns: 5_000,
        scl_wait_ns: 100_000,
        scl_poll_ns: 1_000,
    };
}

/// What the bus clear found and did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Recovery {
    /// SDA was high already: no clock pulses, only the START/STOP.
    Free,
    /// SDA was released after `clocks` pulses (1..=9), then the START/STOP.
    Freed {
        /// Pulses until SDA read high.
        clocks: u8,
    },
    /// SDA low after nine pulses, or again after the STOP: someone holds it.
    SdaStuck,
    /// SCL stayed low for [`RecoveryTiming::scl_wait_ns`] after being released.
    SclHeldLow,
}

impl Recovery {
    /// The bus is idle (both lines high) after the sequence.
    pub fn bus_free(self) -> bool {
        matches!(self, Self::Free | Self::Freed { .. })
    }
}

/// Why SCL did not come up (internal: becomes [`Recovery::SclHeldLow`]).
struct SclHeld;

/// Releases SCL and waits (bounded) until it reads high.
fn release_scl<P: OutputPin + InputPin>(
    scl: &mut P,
    delay: &mut impl DelayNs,
    timing: &RecoveryTiming,
) -> Result<Result<(), SclHeld>, P::Error> {
    scl.set_high()?;
    let mut waited_ns = 0;
    while scl.is_low()? {
        if waited_ns >= timing.scl_wait_ns {
            return Ok(Err(SclHeld));
        }
        delay.delay_ns(timing.scl_poll_ns);
        waited_ns += timing.scl_poll_ns;
    }
    Ok(Ok(()))
}

/// One clock pulse: SCL low for a half period, released, high for a half period.
fn pulse<P: OutputPin + InputPin>(
    scl: &mut P,
    delay: &mut impl DelayNs,
    timing: &RecoveryTiming,
) -> Result<Result<(), SclHeld>, P::Error> {
    scl.set_low()?;
    delay.delay_ns(timing.half_period_ns);
    if let Err(held) = release_scl(scl, delay, timing)? {
        return Ok(Err(held));
    }
    delay.delay_ns(timing.half_period_ns);
    Ok(Ok(()))
}

/// The bus clear (see the module docs). `scl` and `sda` are open-drain lines (high = released);
/// on return both are released. A pin error ends it at once with that error.
pub fn recover<SCL, SDA>(
    scl: &mut SCL,
    sda: &mut SDA,
    delay: &mut impl DelayNs,
    timing: &RecoveryTiming,
) -> Result<Recovery, SCL::Error>
where
    SCL: OutputPin + InputPin,
    SDA: OutputPin + InputPin<Error = SCL::Error>,
{
    sda.set_high()?;
    let outcome = clear(scl, sda, delay, timing);
    sda.set_high()?;
    scl.set_high()?;
    outcome
}

fn clear<SCL, SDA>(
    scl: &mut SCL,
    sda: &mut SDA,
    delay: &mut impl DelayNs,
    timing: &RecoveryTiming,
) -> Result<Recovery, SCL::Error>
where
    SCL: OutputPin + InputPin,
    SDA: OutputPin + InputPin<Error = SCL::Error>,
{
    delay.delay_ns(timing.half_period_ns);
    if release_scl(scl, delay, timing)?.is_err() {
        return Ok(Recovery::SclHeldLow);
    }
    let mut clocks = 0;
    while sda.is_low()? {
        if clocks == MAX_CLOCKS {
            return Ok(Recovery::SdaStuck);
        }
        if pulse(scl, delay, timing)?.is_err() {
            return Ok(Recovery::SclHeldLow);
        }
        clocks += 1;
    }
    // START (SDA falls with SCL high), one clock with SDA low, STOP (SDA rises with SCL high).
    sda.set_low()?;
    delay.delay_ns(timing.half_period_ns);
    if pulse(scl, delay, timing)?.is_err() {
        return Ok(Recovery::SclHeldLow);
    }
    sda.set_high()?;
    delay.delay_ns(timing.half_period_ns);
    Ok(match (sda.is_low()?, clocks) {
        (true, _) => Recovery::SdaStuck,
        (false, 0) => Recovery::Free,
        (false, clocks) => Recovery::Freed { clocks },
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::cell::RefCell;
    use core::convert::Infallible;
    use embedded_hal::digital::ErrorType;

    /// A slave's hold on SDA.
    #[derive(Clone, Copy, Debug, PartialEq)]
    enum Hold {
        /// Low until the n-th SCL falling edge, then released.
        Bits(u32),
        /// Sends these bits (MSB first, `len` of them) from now, one per falling edge, then
        /// releases; a START or STOP ends it at once (as UM10204 requires of every slave).
        Byte { bits: u16, len: u32 },
        /// Low for ever (a short).
        Forever,
    }

    /// The two lines, the master's drive, a slave, and what happened on the wire.
    struct Bus {
        master_scl: bool,
        master_sda: bool,
        hold: Hold,
        /// Falling edges of SCL seen by the slave.
        falls: u32,
        /// SCL held low by a slave for this long after each release by the master, ns.
        stretch_ns: u64,
        /// SCL held low for ever (a short, or a slave that never lets go).
        scl_stuck: bool,
        /// When the master last released SCL, ns (`None`: it never pulled it low).
        released_at_ns: Option<u64>,
        now_ns: u64,
        starts: u32,
        stops: u32,
        /// Shortest SCL low and high phases, ns (the wire's speed).
        min_low_ns: u64,
        min_high_ns: u64,
        scl_changed_at_ns: u64,
        last_scl: bool,
    }

    impl Bus {
        fn new(hold: Hold) -> Self {
            Self {
                master_scl: true,
                master_sda: true,
                hold,
                falls: 0,
                stretch_ns: 0,
                scl_stuck: false,
                released_at_ns: None,
                now_ns: 0,
                starts: 0,
                stops: 0,
                min_low_ns: u64::MAX,
                min_high_ns: u64::MAX,
                scl_changed_at_ns: 0,
                last_scl: true,
            }
        }

        fn scl(&self) -> bool {
            let stretched = self
                .released_at_ns
                .is_some_and(|t| self.now_ns - t < self.stretch_ns);
            self.master_scl && !stretched && !self.scl_stuck
        }

        fn slave_sda(&self) -> bool {
            match self.hold {
                Hold::Bits(n) => self.falls >= n,
                Hold::Byte { bits, len } => {
                    self.falls >= len || bits & (1 << (len - 1 - self.falls)) != 0
                }
                Hold::Forever => false,
            }
        }

        fn sda(&self) -> bool {
            self.master_sda && self.slave_sda()
        }

        /// Records the SCL phase that just ended.
        fn track_scl(&mut self) {
            let scl = self.scl();
            if scl != self.last_scl {
                let phase = self.now_ns - self.scl_changed_at_ns;
                if self.last_scl {
                    self.min_high_ns = self.min_high_ns.min(phase);
                } else {
                    self.min_low_ns = self.min_low_ns.min(phase);
                }
                self.scl_changed_at_ns = self.now_ns;
                self.last_scl = scl;
            }
        }

        fn drive(&mut self, line: Line, high: bool) {
            self.track_scl();
            let (scl_before, sda_before) = (self.scl(), self.sda());
            match line {
                Line::Scl => {
                    if high && !self.master_scl {
                        self.released_at_ns = Some(self.now_ns);
                    }
                    self.master_scl = high;
                }
                Line::Sda => self.master_sda = high,
            }
            if scl_before && !self.scl() {
                self.falls += 1;
            }
            if scl_before && self.scl() && sda_before != self.sda() {
                if self.sda() {
                    self.stops += 1;
                } else {
                    self.starts += 1;
                }
                // A START or STOP resets the slave: it lets go of SDA.
                self.hold = Hold::Bits(0);
            }
            self.track_scl();
        }
    }

    #[derive(Clone, Copy)]
    enum Line {
        Scl,
        Sda,
    }

    struct Pin<'a> {
        bus: &'a RefCell<Bus>,
        line: Line,
    }

    impl ErrorType for Pin<'_> {
        type Error = Infallible;
    }

    impl OutputPin for Pin<'_> {
        fn set_low(&mut self) -> Result<(), Infallible> {
            self.bus.borrow_mut().drive(self.line, false);
            Ok(())
        }
        fn set_high(&mut self) -> Result<(), Infallible> {
            self.bus.borrow_mut().drive(self.line, true);
            Ok(())
        }
    }

    impl InputPin for Pin<'_> {
        fn is_high(&mut self) -> Result<bool, Infallible> {
            let bus = self.bus.borrow();
            Ok(match self.line {
                Line::Scl => bus.scl(),
                Line::Sda => bus.sda(),
            })
        }
        fn is_low(&mut self) -> Result<bool, Infallible> {
            self.is_high().map(|h| !h)
        }
    }

    struct Delay<'a>(&'a RefCell<Bus>);

    impl DelayNs for Delay<'_> {
        fn delay_ns(&mut self, ns: u32) {
            let mut bus = self.0.borrow_mut();
            bus.now_ns += u64::from(ns);
            bus.track_scl();
        }
    }

    fn run(bus: Bus) -> (Recovery, Bus) {
        let bus = RefCell::new(bus);
        let mut scl = Pin {
            bus: &bus,
            line: Line::Scl,
        };
        let mut sda = Pin {
            bus: &bus,
            line: Line::Sda,
        };
        let Ok(outcome) = recover(
            &mut scl,
            &mut sda,
            &mut Delay(&bus),
            &RecoveryTiming::STANDARD,
        );
        (outcome, bus.into_inner())
    }

    /// Both lines released at the end, whatever happened.
    fn assert_released(bus: &Bus) {
        assert!(bus.master_scl && bus.master_sda);
    }

    #[test]
    fn a_slave_holding_sda_for_k_bits_is_freed_after_k_clocks() {
        for k in 0..=u32::from(MAX_CLOCKS) {
            let (outcome, bus) = run(Bus::new(Hold::Bits(k)));
            let expected = match k {
                0 => Recovery::Free,
                k => Recovery::Freed { clocks: k as u8 },
            };
            assert_eq!(outcome, expected, "k = {k}");
            assert!(outcome.bus_free());
            // k pulses, then the START/STOP's one; the bus ends idle with a STOP.
            assert_eq!(bus.falls, k + 1, "k = {k}");
            assert_eq!((bus.starts, bus.stops), (1, 1), "k = {k}");
            assert!(bus.scl() && bus.sda());
            assert_released(&bus);
            // 100 kHz: no SCL phase shorter than the half period (the wire's 5 us).
            assert!(
                bus.min_low_ns >= 5_000 && bus.min_high_ns >= 5_000,
                "k = {k}"
            );
            // Bounded: 1 + 2 k + 1 + 2 + 1 half periods; nothing stretches here.
            assert_eq!(bus.now_ns, u64::from(2 * k + 5) * 5_000, "k = {k}");
        }
    }

    #[test]
    fn sda_held_beyond_nine_clocks_or_for_ever_is_stuck() {
        for hold in [Hold::Bits(10), Hold::Bits(1000), Hold::Forever] {
            let (outcome, bus) = run(Bus::new(hold));
            assert_eq!(outcome, Recovery::SdaStuck, "{hold:?}");
            assert!(!outcome.bus_free());
            // Nine pulses and no more; no START or STOP (SDA never rose).
            assert_eq!(bus.falls, u32::from(MAX_CLOCKS), "{hold:?}");
            assert_eq!((bus.starts, bus.stops), (0, 0));
            assert_released(&bus);
            assert_eq!(bus.now_ns, (1 + 2 * 9) * 5_000);
        }
    }

    #[test]
    fn a_slave_released_on_a_one_bit_is_reset_by_the_start() {
        // Mid-byte: 0, 1, then 0s; SDA rises after the first pulse, the slave would drive the
        // STOP's bit low but the START resets it first.
        let (outcome, bus) = run(Bus::new(Hold::Byte {
            bits: 0b0_1000_0000,
            len: 9,
        }));
        assert_eq!(outcome, Recovery::Freed { clocks: 1 });
        assert_eq!((bus.starts, bus.stops), (1, 1));
        assert!(bus.sda());
        assert_released(&bus);
    }

    #[test]
    fn scl_held_low_stops_the_sequence_within_its_bound() {
        let mut bus = Bus::new(Hold::Bits(3));
        bus.scl_stuck = true;
        let (outcome, bus) = run(bus);
        assert_eq!(outcome, Recovery::SclHeldLow);
        assert_eq!(bus.falls, 0);
        assert_released(&bus);
        // One half period, then the wait's bound (100 us) and no more.
        let waited = bus.now_ns - 5_000;
        assert!((100_000..=101_000).contains(&waited), "{waited} ns");
    }

    #[test]
    fn clock_stretching_within_the_bound_is_waited_for() {
        let mut bus = Bus::new(Hold::Bits(4));
        bus.stretch_ns = 30_000;
        let (outcome, bus) = run(bus);
        assert_eq!(outcome, Recovery::Freed { clocks: 4 });
        assert_eq!((bus.starts, bus.stops), (1, 1));
        assert!(bus.min_high_ns >= 5_000);
        // Each of the five releases (four pulses, the STOP's clock) waited 30 us on top of the
        // 13 half periods.
        assert_eq!(bus.now_ns, 13 * 5_000 + 5 * 30_000);
    }

    #[test]
    fn clock_stretching_beyond_the_bound_is_scl_held_low() {
        let mut bus = Bus::new(Hold::Bits(4));
        bus.stretch_ns = 150_000;
        // The first release (at the start) is not stretched: SCL was high already.
        let (outcome, bus) = run(bus);
        assert_eq!(outcome, Recovery::SclHeldLow);
        assert_eq!(bus.falls, 1);
        assert_released(&bus);
    }
}
