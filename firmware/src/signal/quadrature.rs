//! Software x4 quadrature decoder for comparator states that arrive as samples.
//!
//! Used where the two fringe comparators are sampled instead of counted by the encoder timer:
//! the simulator, or a board that samples them at a fixed rate (which must then be well above
//! the peak edge rate, about 2.4 M edges/s for the docs/physics.md parameter set, or edges alias
//! into illegal transitions).
//!
//! # Sample format and sign convention
//!
//! One `u8` per sample: bit 0 = comparator A (channel A ~ cos psi_H, 1 when cos psi_H > 0),
//! bit 1 = comparator B (channel B ~ sin psi_H, 1 when sin psi_H > 0); other bits are ignored.
//! With ideal comparators the state fixes the quadrant of psi_H:
//!
//! | psi_H quadrant | 0: [0, 90) deg | 1: [90, 180) | 2: [180, 270) | 3: [270, 360) |
//! |---|---|---|---|---|
//! | (A, B) | (1, 1) | (0, 1) | (0, 0) | (1, 0) |
//! | state `B<<1 \| A` | 3 | 2 | 0 | 1 |
//!
//! Increasing psi_H (3 -> 2 -> 0 -> 1 -> 3) counts **up**. The decoder starts its count at the
//! quadrant of the first sample, so with ideal comparators `count = floor(psi_H / (pi/2)) + 4 n`
//! always holds (`count mod 4` is the quadrant). A board with swapped or inverted comparators
//! maps its bits before the decoder or flips the count sign in
//! [`crate::signal::fringe_phase::FringeConvention`].
//!
//! # Illegal transitions
//!
//! Both bits changing between two samples is a jump of two quadrants whose direction is unknown
//! (an edge was missed: sampling too slow, or a glitch). It is counted in
//! [`QuadratureDecoder::illegal_transitions`] and contributes **no** motion; the new state is
//! taken as the reference, so the count is then off by +-2 (half a fringe) until fixed upstream
//! (the fractional fringe of [`crate::signal::fringe_phase`] flags such a disagreement).
//!
//! # Hot path
//!
//! [`QuadratureDecoder::decode`] runs a rolling 4-bit index `(previous << 2) | current` into a
//! 16-entry table whose entries pack the step and the illegal flag into one `u32`
//! (`(step + 1) | illegal << 16`), so each sample is one load, one table load and one add.
//! Sums are exact over chunks of [`CHUNK`] samples and unpacked per chunk. The Thumb-2 inner
//! loop is 8 instructions per sample at `opt-level = "s"` (`ldrb` post-increment, `and`, `bfi`,
//! `ldr`, `mov`, `add`, `subs`, `bne`): 8.0 instructions per sample counted in QEMU
//! (`-icount`, 4096-sample batch). Cycles on the M4 are more (two loads, a taken branch): an
//! estimated 11 to 13 per sample, so about 13 M samples/s at 168 MHz if the core did nothing
//! else. Each sample carries at most one edge, so the sample rate, not the decoder, bounds the
//! edge rate; sampling at twice the 2.4 M edges/s peak would take about 40 % of the CPU. The
//! cycle figures are estimates, not measured on a board.

/// Quadrant of psi_H (0..=3) for each comparator state `B<<1 | A` (see the module table).
pub const QUADRANT_OF_STATE: [u8; 4] = [2, 3, 1, 0];

/// Result of one transition.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Transition {
    /// Same state: no edge.
    Still,
    /// One edge forwards (psi_H increased by a quarter fringe): +1.
    Forward,
    /// One edge backwards: -1.
    Backward,
    /// Both comparators changed: direction unknown, not counted as motion.
    Illegal,
}

impl Transition {
    /// The step in x4 counts (+1, -1, 0; 0 for an illegal transition).
    #[inline]
    pub const fn step(self) -> i8 {
        match self {
            Transition::Forward => 1,
            Transition::Backward => -1,
            Transition::Still | Transition::Illegal => 0,
        }
    }
}

/// The transition from state `previous` to `current` (both `B<<1 | A`, other bits ignored).
#[inline]
pub const fn transition(previous: u8, current: u8) -> Transition {
    let q0 = QUADRANT_OF_STATE[(previous & 3) as usize];
    let q1 = QUADRANT_OF_STATE[(current & 3) as usize];
    match q1.wrapping_sub(q0) & 3 {
        0 => Transition::Still,
        1 => Transition::Forward,
        3 => Transition::Backward,
        _ => Transition::Illegal,
    }
}

/// Packed table entry: `(step + 1)` in bits 0..16, the illegal flag in bits 16..32.
const fn packed(t: Transition) -> u32 {
    let illegal = matches!(t, Transition::Illegal) as u32;
    ((t.step() + 1) as u32) | (illegal << 16)
}

const fn build_table() -> [u32; 16] {
    let mut table = [0u32; 16];
    let mut i = 0;
    while i < 16 {
        table[i] = packed(transition((i >> 2) as u8, i as u8));
        i += 1;
    }
    table
}

/// Index `(previous << 2) | current` -> packed `(step + 1) | illegal << 16`.
const TRANSITION_TABLE: [u32; 16] = build_table();

/// Samples per chunk of [`QuadratureDecoder::decode`]: the low field sums at most
/// `2 * CHUNK < 2^16`, so it never carries into the illegal field.
pub const CHUNK: usize = 32_767;

/// Software x4 decoder state: the last comparator state, the 64-bit count, illegal transitions.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct QuadratureDecoder {
    state: u8,
    count: i64,
    illegal_transitions: u32,
}

impl QuadratureDecoder {
    /// Starts at the state of the first sample; the count starts at that state's quadrant.
    pub const fn new(initial_sample: u8) -> Self {
        let state = initial_sample & 3;
        Self {
            state,
            count: QUADRANT_OF_STATE[state as usize] as i64,
            illegal_transitions: 0,
        }
    }

    /// The x4 count (quarter fringes), 64-bit: at 2.4 M edges/s it wraps after 10^5 years.
    #[inline]
    pub const fn count(&self) -> i64 {
        self.count
    }

    /// Illegal transitions seen since construction (saturating).
    #[inline]
    pub const fn illegal_transitions(&self) -> u32 {
        self.illegal_transitions
    }

    /// The last comparator state `B<<1 | A`.
    #[inline]
    pub const fn state(&self) -> u8 {
        self.state
    }

    /// One sample.
    #[inline]
    pub fn step(&mut self, sample: u8) -> Transition {
        let current = sample & 3;
        let t = transition(self.state, current);
        self.state = current;
        self.count = self.count.wrapping_add(t.step() as i64);
        if let Transition::Illegal = t {
            self.illegal_transitions = self.illegal_transitions.saturating_add(1);
        }
        t
    }

    /// A batch of samples (the hot path). Returns the net step of this batch in x4 counts
    /// (illegal transitions count 0); the count and illegal counter are updated.
    pub fn decode(&mut self, samples: &[u8]) -> i64 {
        let mut net: i64 = 0;
        let mut illegal: u32 = 0;
        let mut index = self.state as usize;
        for chunk in samples.chunks(CHUNK) {
            let mut sum: u32 = 0;
            for &s in chunk {
                index = ((index << 2) | (s & 3) as usize) & 15;
                sum = sum.wrapping_add(TRANSITION_TABLE[index]);
            }
            // Low field: sum of (step + 1) over the chunk; high field: illegal transitions.
            let steps_plus_one = (sum & 0xFFFF) as i64;
            net = net.wrapping_add(steps_plus_one - chunk.len() as i64);
            illegal = illegal.saturating_add(sum >> 16);
        }
        self.state = (index & 3) as u8;
        self.count = self.count.wrapping_add(net);
        self.illegal_transitions = self.illegal_transitions.saturating_add(illegal);
        net
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::test_rng::XorShift;

    /// Comparator state of ideal comparators at quadrant `q` of psi_H, from the physics
    /// (A = cos > 0, B = sin > 0 at the quadrant's centre), independent of the table.
    fn state_of_quadrant(q: i64) -> u8 {
        let psi = (q.rem_euclid(4) as f64 + 0.5) * std::f64::consts::FRAC_PI_2;
        let a = (psi.cos() > 0.0) as u8;
        let b = (psi.sin() > 0.0) as u8;
        (b << 1) | a
    }

    /// All 16 transitions against the independent definition: same state = still, one bit
    /// changed = one quadrant forward or back (from the physics), both bits = illegal.
    #[test]
    fn exhaustive_transition_table() {
        for prev_q in 0..4i64 {
            let prev = state_of_quadrant(prev_q);
            assert_eq!(QUADRANT_OF_STATE[prev as usize] as i64, prev_q);
            for cur in 0..4u8 {
                let expected = if cur == prev {
                    Transition::Still
                } else if cur == state_of_quadrant(prev_q + 1) {
                    Transition::Forward
                } else if cur == state_of_quadrant(prev_q - 1) {
                    Transition::Backward
                } else {
                    assert_eq!(cur ^ prev, 3, "only the both-bits change is left");
                    Transition::Illegal
                };
                assert_eq!(transition(prev, cur), expected, "{prev} -> {cur}");
                // The packed hot-path table agrees with the scalar one.
                let mut d = QuadratureDecoder::new(prev);
                let net = d.decode(&[cur]);
                assert_eq!(net, expected.step() as i64);
                assert_eq!(
                    d.illegal_transitions(),
                    (expected == Transition::Illegal) as u32
                );
            }
        }
        // Upper bits of a sample are ignored.
        assert_eq!(transition(0xFC | 3, 0xF0 | 2), Transition::Forward);
    }

    /// A long random walk of psi_H quadrants (steps -1, 0, +1 and occasional +-2 jumps) against
    /// a reference counter. Exact: the decoder must reproduce the true count minus the
    /// unknowable +-2 jumps, and count exactly those as illegal.
    #[test]
    fn long_random_walk_matches_reference() {
        let mut rng = XorShift(0xDEAD_BEEF_1234_5678);
        let mut q: i64 = 7; // true quadrant count
        let mut decoder = QuadratureDecoder::new(state_of_quadrant(q));
        let mut scalar = decoder;
        let mut reference_count = QUADRANT_OF_STATE[state_of_quadrant(q) as usize] as i64;
        let mut jumps = 0u32;
        let mut samples = Vec::new();
        for _ in 0..2_000_000 {
            let r = rng.next() % 64;
            let step = match r {
                0 => 2,
                1 => -2,
                2..=22 => 1,
                23..=43 => -1,
                _ => 0,
            };
            q += step;
            if step.abs() == 2 {
                jumps += 1;
            } else {
                reference_count += step;
            }
            let s = state_of_quadrant(q) | ((rng.next() as u8) & 0xFC); // junk upper bits
            samples.push(s);
            scalar.step(s);
        }
        // Batch in uneven pieces to exercise chunk and call boundaries.
        let mut rest = &samples[..];
        let mut total = 0;
        while !rest.is_empty() {
            let n = ((rng.next() % 100_000) as usize).min(rest.len());
            total += decoder.decode(&rest[..n]);
            rest = &rest[n..];
        }
        assert_eq!(decoder.count(), reference_count);
        assert_eq!(scalar, decoder);
        assert_eq!(decoder.illegal_transitions(), jumps);
        assert_eq!(
            total + QUADRANT_OF_STATE[state_of_quadrant(7) as usize] as i64,
            decoder.count()
        );
        // count mod 4 is the quadrant of psi_H when no jump was lost in a way that shifts it:
        // each lost +-2 jump shifts it by 2, so parity of jumps decides.
        let shift = if jumps.is_multiple_of(2) { 0 } else { 2 };
        assert_eq!((decoder.count() + shift).rem_euclid(4), q.rem_euclid(4));
    }

    /// A batch longer than one chunk of all-forward edges: no carry between packed fields.
    #[test]
    fn chunk_boundaries_exact() {
        let seq = [3u8, 2, 0, 1];
        let samples: Vec<u8> = (1..=3 * CHUNK + 5).map(|i| seq[i % 4]).collect();
        let mut d = QuadratureDecoder::new(3);
        assert_eq!(d.decode(&samples), (3 * CHUNK + 5) as i64);
        assert_eq!(d.illegal_transitions(), 0);
        let illegal: Vec<u8> = (0..2 * CHUNK + 1)
            .map(|i| if i % 2 == 0 { 0 } else { 3 })
            .collect();
        let mut d = QuadratureDecoder::new(3);
        assert_eq!(d.decode(&illegal), 0);
        assert_eq!(d.illegal_transitions(), (2 * CHUNK + 1) as u32);
        assert_eq!(d.decode(&[]), 0);
    }
}
