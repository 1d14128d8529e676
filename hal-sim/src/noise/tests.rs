//! The noise's tests: the random walk's variance, reproducibility per (seed, segment), and the
//! grid snapped to the driven dither's segment starts.

use super::*;
use crate::dither::drive::DriveSegment;
use crate::dither::open_loop::OpenLoopDrive;
use crate::dither::resonator::ResonatorParams;

#[test]
fn random_walk_variance_matches_arw() {
    let p = GyroParams {
        arw_deg_per_rt_h: 0.1,
        ..Default::default()
    };
    let d = p.derive().unwrap();
    let n = Noise::new(&p, &d);
    let dither = Dither::new(&p.dither_spec(&d));
    assert!(!n.snaps());
    // Increments over 1 s windows: variance ARW^2 * 1 s. 2000 windows: 3 % rel. std.
    let mut s2 = 0.0;
    let windows = 2000;
    let mut prev = n.angle_rad(0.0, &dither);
    for i in 1..=windows {
        let a = n.angle_rad(i as f64, &dither);
        s2 += (a - prev).powi(2);
        prev = a;
    }
    let var = s2 / windows as f64;
    let expect = d.arw_rad_per_rt_s.powi(2);
    assert!((var / expect - 1.0).abs() < 0.1, "{var} vs {expect}");
}

#[test]
fn angle_is_continuous_and_reproducible() {
    let p = GyroParams {
        arw_deg_per_rt_h: 0.1,
        ..Default::default()
    };
    let d = p.derive().unwrap();
    let dither = Dither::new(&p.dither_spec(&d));
    let n1 = Noise::new(&p, &d);
    let n2 = Noise::new(&p, &d);
    for k in [1u64, 5, 1023, 1024, 5000] {
        let t = n1.segment_start_s(k);
        let mut a = [0.0; 1];
        let mut b = [0.0; 1];
        n1.angle_jet(t, k - 1, &dither, &mut a);
        n1.angle_jet(t, k, &dither, &mut b);
        assert!((a[0] - b[0]).abs() < 1e-12);
        assert_eq!(
            n1.angle_rad(t + 1e-4, &dither).to_bits(),
            n2.angle_rad(t + 1e-4, &dither).to_bits()
        );
        assert_eq!(n1.segment_index(t), k);
    }
}

/// A driven gyro at the nominal 389 Hz with the noise on, its dither, and its noise.
fn driven(arw_deg_per_rt_h: f64) -> (GyroParams, Dither, Noise) {
    let p = GyroParams {
        arw_deg_per_rt_h,
        ..Default::default()
    }
    .with_steady_driven_dither(ResonatorParams::default());
    let d = p.derive().unwrap();
    (p, Dither::new(&p.dither_spec(&d)), Noise::new(&p, &d))
}

/// Drive segments starting every 2 to 41 ticks (25 us), pseudo-randomly: many starts per
/// snap window, some windows without one.
fn scattered_drive(p: &GyroParams, until_s: f64) -> Vec<DriveSegment> {
    let drive = p.open_loop_drive().unwrap();
    let tick = 1.0 / 40_000.0;
    let mut x: u64 = 0x9e37_79b9_7f4a_7c15;
    let mut n = 0u64;
    let mut out = Vec::new();
    loop {
        x = x
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        n += 2 + (x >> 33) % 40;
        let start_s = n as f64 * tick;
        if start_s > until_s {
            return out;
        }
        out.push(DriveSegment {
            start_s,
            ..drive.segment(0)
        });
    }
}

/// Pushes `drive` into `dither` until it is known until `until_s`.
fn feed(drive: &mut OpenLoopDrive, dither: &mut Dither, until_s: f64) {
    let d = dither.driven_mut().unwrap();
    while d.known_until_s() < until_s {
        d.push(drive.next_segment()).unwrap();
    }
}

/// The decided segments `(start, end, rate, angle)` of a snapped grid.
fn decided(n: &Noise) -> Vec<(f64, f64, f64, f64)> {
    let g = n.grid.borrow();
    g.decided
        .iter()
        .map(|s| (s.start_s, s.end_s, s.rate, s.angle))
        .collect()
}

/// Every boundary is the first drive start in its window, or the nominal time if the
/// window has none; the open-loop drive (segment starts at the rate peaks) snaps them all.
#[test]
fn boundaries_snap_to_the_first_drive_start_in_their_window() {
    let (p, mut dither, n) = driven(0.01);
    assert!(n.snaps());
    let w = n.snap_window_s();
    assert!((w - 1.0 / (8.0 * 389.0)).abs() < 1e-15);
    let starts: Vec<f64> = scattered_drive(&p, 0.3).iter().map(|s| s.start_s).collect();
    for s in scattered_drive(&p, 0.3) {
        dither.driven_mut().unwrap().push(s).unwrap();
    }
    let known = n.known_until_s(&dither);
    let segs = decided(&n);
    let mut snapped = 0;
    for (k, &(start, end, _, _)) in segs.iter().enumerate() {
        let e = n.segment_end_s(k as u64);
        let first = starts.iter().find(|&&s| s >= e - w && s < e + w);
        match first {
            Some(&s) => {
                assert_eq!(end, s, "{k}");
                snapped += 1;
            }
            None => assert_eq!(end, e, "{k}"),
        }
        assert!(end > start);
    }
    assert!(
        snapped > 150 && snapped < segs.len(),
        "{snapped} of {}",
        segs.len()
    );
    // The horizon: the start of the first undecided segment, less than 3/4 of a nominal
    // period before the drive's.
    let drive_known = dither.known_until_s();
    assert_eq!(known, segs.last().unwrap().1);
    assert!(known <= drive_known && known > drive_known - 0.75 / 389.0);

    let (p, mut dither, n) = driven(0.01);
    let mut drive = p.open_loop_drive().unwrap();
    feed(&mut drive, &mut dither, 0.3);
    let segs = decided(&n.clone());
    let _ = n.known_until_s(&dither);
    let segs2 = decided(&n);
    assert!(segs.is_empty() && segs2.len() > 200);
    let mut offsets = (f64::INFINITY, f64::NEG_INFINITY);
    for (k, &(_, end, _, _)) in segs2.iter().enumerate() {
        let e = n.segment_end_s(k as u64);
        // The rate peaks of the steady open-loop drive: a few ticks off the nominal grid.
        assert!(end != e && (end - e).abs() < w, "{k}: {end} vs {e}");
        assert_eq!(drive.segment(k as u64 + 1).start_s, end);
        offsets = (offsets.0.min(end - e), offsets.1.max(end - e));
    }
    eprintln!(
        "open-loop drive starts {:.1} to {:.1} us after the nominal grid",
        offsets.0 * 1e6,
        offsets.1 * 1e6
    );
}

/// Segment `k`'s increment is `ARW sqrt(d_k) z_k` with its actual length `d_k` and the
/// nominal grid's Gaussian `z_k` (its rate there times `sqrt(T/2)`), and the angle is
/// continuous at every boundary.
#[test]
fn snapped_segments_scale_the_nominal_gaussians_by_their_length() {
    let (p, mut dither, n) = driven(0.05);
    for s in scattered_drive(&p, 3.0) {
        dither.driven_mut().unwrap().push(s).unwrap();
    }
    let ideal = {
        let q = GyroParams {
            arw_deg_per_rt_h: 0.05,
            ..Default::default()
        };
        Noise::new(&q, &q.derive().unwrap())
    };
    let _ = n.known_until_s(&dither);
    let segs = decided(&n);
    assert!(segs.len() > 2000, "{}", segs.len());
    let sigma = n.sigma_rad_per_rt_s;
    for (k, w) in segs.windows(2).enumerate() {
        let (start, end, rate, angle) = w[0];
        let k = k as u64;
        let nominal = ideal.segment_end_s(k) - ideal.segment_start_s(k);
        let z = ideal.segment(k).0 * nominal.sqrt() / sigma;
        let z_here = rate * (end - start).sqrt() / sigma;
        assert!(
            (z_here - z).abs() <= 1e-14 * z.abs().max(1.0),
            "{k}: {z_here} vs {z}"
        );
        // The increment is rate * length: ARW sqrt(d_k) z_k.
        assert_eq!(w[1].3, angle + rate * (end - start));
        assert_eq!(w[1].0, end);
        // Continuous: the segment's formula at its end gives the next one's start angle.
        let mut a = [0.0; 2];
        n.angle_jet(end, k, &dither, &mut a);
        assert_eq!(a[0], w[1].3);
        assert_eq!(a[1], rate);
    }
}

/// What the noise says at a time never changes once it is known, however the drive comes:
/// pushed segment by segment and asked after each push, or all at once.
#[test]
fn the_snapped_grid_depends_on_the_drive_alone() {
    let (p, mut dither, n) = driven(0.05);
    let segments = scattered_drive(&p, 0.5);
    let mut seen: Vec<(f64, u64, f64)> = Vec::new();
    let mut t = 0.0;
    for s in &segments {
        let driven = dither.driven_mut().unwrap();
        driven.push(*s).unwrap();
        if s.start_s > 0.2 {
            driven.extend_until(s.start_s + 1e-5).unwrap();
        }
        let known = n.known_until_s(&dither);
        assert!(known <= dither.known_until_s());
        // Times up to the horizon: their segment, and the angle there.
        while t + 3.7e-5 < known {
            t += 3.7e-5;
            let k = n.segment_at(t, &dither);
            seen.push((t, k, n.angle_rad(t, &dither)));
        }
    }
    let (_, mut all, m) = driven(0.05);
    for s in &segments {
        all.driven_mut().unwrap().push(*s).unwrap();
    }
    assert!(seen.len() > 10_000);
    for &(t, k, a) in &seen {
        assert_eq!(m.segment_at(t, &all), k, "{t}");
        assert_eq!(m.angle_rad(t, &all).to_bits(), a.to_bits(), "{t}");
    }
    // Beyond the horizon the noise refuses the rate (and knows the angle at the horizon).
    let h = m.known_until_s(&all);
    let k = m.segment_at(h, &all);
    let mut one = [0.0; 1];
    m.angle_jet(h, k, &all, &mut one);
    assert_eq!(one[0].to_bits(), m.grid.borrow().open_angle.to_bits());
    let (m, all) = (m.clone(), all.clone());
    let rate = std::panic::catch_unwind(std::panic::AssertUnwindSafe(move || {
        let mut two = [0.0; 2];
        m.angle_jet(h, k, &all, &mut two);
    }));
    assert!(rate.is_err());
}

/// The random walk with a driven dither whose segment starts slide through the snap
/// windows (drive at 392 Hz, nominal 389 Hz: segments from T/4 to 3T/4 long): the
/// variance of the increments over 50 ms windows is ARW^2 * 50 ms (2000 windows: 3 % rel.
/// std).
#[test]
fn driven_random_walk_variance_matches_arw() {
    let (p, mut dither, n) = driven(0.1);
    let r = *p.resonator().unwrap();
    let mut drive = OpenLoopDrive::tuned(&r, 392.0, 450.0);
    let (windows, len) = (2000, 0.05);
    feed(&mut drive, &mut dither, windows as f64 * len + 0.01);
    let mut s2 = 0.0;
    let mut prev = n.angle_rad(0.0, &dither);
    for i in 1..=windows {
        let a = n.angle_rad(i as f64 * len, &dither);
        s2 += (a - prev).powi(2);
        prev = a;
    }
    let var = s2 / windows as f64;
    let expect = n.sigma_rad_per_rt_s.powi(2) * len;
    assert!((var / expect - 1.0).abs() < 0.1, "{var} vs {expect}");
    // The lengths really vary: about half of the boundaries snap (segments of 0.99 T/2),
    // and at the end of each snapped run a segment lasts ~T/2 + W.
    let segs = decided(&n);
    let nominal = 0.5 / 389.0;
    let snapped = (0..segs.len())
        .filter(|&k| segs[k].1 != n.segment_end_s(k as u64))
        .count();
    let long = segs.iter().filter(|x| x.1 - x.0 > 1.2 * nominal).count();
    eprintln!("{} segments, {snapped} snapped, {long} long", segs.len());
    assert!(
        snapped > segs.len() * 2 / 5 && snapped < segs.len() * 3 / 5,
        "{snapped}"
    );
    assert!(long > 500, "{long}");
}
