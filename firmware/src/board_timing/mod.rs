//! The board's timing arithmetic and its watch over its own timing, as plain functions: built
//! and tested on the host, called by `board/` (the registers) and by hal-sim's simulated board.
//!
//! | file | what |
//! |---|---|
//! | [`compare`] | the next compare of a periodic event after its handler ran late (a pause of up to seconds), and the periods missed |
//! | [`monitor`] | the rate monitors: each periodic event counted, a rate off for longer than its hold named as a fault |
//! | [`selftest`] | the power-up self-test's verdicts from what the board measured |
//! | [`health`] | the self-test and the timing faults together, as `status` and `selftest` report them |
//! | [`phase`] | the drive tick's phase (TIM4) at any TIM2 instant, across TIM2's wraps; the keep-out window anchored at the counters read now |
//!
//! Every time here is a 32-bit counter value of the 84 MHz APB1 timers (TIM2, TIM4): it wraps
//! every 51 s, so every comparison is of wrapping differences, and every function states the
//! span over which it is valid.

pub mod compare;
pub mod health;
pub mod monitor;
pub mod phase;
pub mod selftest;
