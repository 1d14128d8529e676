//! The signal chain: fringe counting -> turnaround sampling -> P1/P2 -> compensation -> output.
