//! The kernels against scalar references (and the AVX2 forms against the portable ones where
//! the machine has AVX2).

use super::*;

#[test]
fn division_is_exact_for_every_luma_sum() {
    for x in 0..=255 * 9999 + 5000u32 {
        assert_eq!(floor_div_10000(x), x / 10000, "x = {x}");
    }
}

#[test]
fn luma_is_exact_for_every_colour() {
    // Every (r, g, b) on a coarse lattice plus the extremes, against integer division.
    let mut r = Vec::new();
    let mut g = Vec::new();
    let mut b = Vec::new();
    for rv in (0..=255u32).step_by(3).chain([254, 255]) {
        for gv in (0..=255u32).step_by(5).chain([254, 255]) {
            for bv in (0..=255u32).step_by(7).chain([254, 255]) {
                r.push(rv as u8);
                g.push(gv as u8);
                b.push(bv as u8);
            }
        }
    }
    let mut out = vec![0u8; r.len()];
    luma601_planar(&r, &g, &b, &mut out);
    for i in 0..out.len() {
        let x = 2989 * u32::from(r[i]) + 5870 * u32::from(g[i]) + 1140 * u32::from(b[i]) + 5000;
        assert_eq!(
            u32::from(out[i]),
            x / 10000,
            "rgb {} {} {}",
            r[i],
            g[i],
            b[i]
        );
    }
}

#[test]
fn excess_sums_match_a_brute_force_count() {
    let stride = 101;
    let pixels: Vec<u8> = (0..stride * 9)
        .map(|i| ((i * 89 + 13) % 256) as u8)
        .collect();
    for cols in [1, 5, 31, 32, 33, 64, 70, 101] {
        for rows in [1, 2, 9] {
            for t in [0, 90, 200, 255] {
                let mut want = [0u64; 3];
                for r in 0..rows {
                    for c in 0..cols {
                        let w = u64::from(pixels[r * stride + c].saturating_sub(t));
                        want[0] += w;
                        want[1] += w * c as u64;
                        want[2] += w * r as u64;
                    }
                }
                let what = format!("{cols} x {rows}, level {t}");
                assert_eq!(excess_sums(&pixels, stride, cols, rows, t), want, "{what}");
                assert_eq!(excess_sums_portable(&pixels, stride, cols, rows, t), want);
                // The last row's tail copied instead of read in place.
                let exact = &pixels[..(rows - 1) * stride + cols];
                assert_eq!(excess_sums(exact, stride, cols, rows, t), want, "{what}");
            }
        }
    }
}

#[test]
fn ring_plane_equals_the_portable_loops() {
    // Sides of 5 to 40 values on a sloped background with noise, some with a neighbour's
    // bright edge (the outlier pass) and some flat: the dispatched plane (AVX2 where the
    // CPU has it) equals the portable one exactly.
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut next = |m: u64| {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state % m
    };
    let mut outliers = 0;
    for case in 0..3000 {
        let (nw, nh) = (5 + next(36) as usize, 7 + next(36) as usize);
        let (gx, gy) = (next(7) as f32 - 3.0, next(7) as f32 - 3.0);
        let noise = next(4);
        let mut px = |x: usize, y: usize| {
            let v = 120.0 + gx * x as f32 * 0.3 + gy * y as f32 * 0.3 + next(2 * noise + 1) as f32;
            v as u8
        };
        let top: Vec<u8> = (0..nw).map(|x| px(x, 0)).collect();
        let mut bottom: Vec<u8> = (0..nw).map(|x| px(x, nh - 1)).collect();
        let left: Vec<u8> = (1..nh - 1).map(|y| px(0, y)).collect();
        let right: Vec<u8> = (1..nh - 1).map(|y| px(nw - 1, y)).collect();
        if case % 3 == 0 {
            let at = next(nw as u64) as usize;
            for v in &mut bottom[at..(at + 4).min(nw)] {
                *v = 250;
            }
        }
        let sides = RingSides {
            top: &top,
            bottom: &bottom,
            left: &left,
            right: &right,
            xm: 0.5 * (nw - 1) as f32,
            ym: 0.5 * (nh - 1) as f32,
        };
        let (got, want) = (ring_plane_on(Avx2::detect(), &sides), sides.plane());
        let bits =
            |p: Option<(f32, f32, f32)>| p.map(|(a, b, c)| (a.to_bits(), b.to_bits(), c.to_bits()));
        assert_eq!(bits(got), bits(want), "case {case}: {nw} x {nh}");
        let first = sides.plane_of_means([
            top.iter().map(|&v| f32::from(v)).sum::<f32>() / nw as f32,
            bottom.iter().map(|&v| f32::from(v)).sum::<f32>() / nw as f32,
            left.iter().map(|&v| f32::from(v)).sum::<f32>() / left.len() as f32,
            right.iter().map(|&v| f32::from(v)).sum::<f32>() / right.len() as f32,
        ]);
        outliers += usize::from((first.0 - want.unwrap().0).abs() > 1e-3);
    }
    assert!(outliers > 300, "the outlier pass ran {outliers} times");
}

#[test]
fn ellipse_window_sums_match_scalar() {
    let stride = 31;
    let pixels: Vec<u8> = (0..stride * 12)
        .map(|i| ((i * 53 + 7) % 256) as u8)
        .collect();
    let e = EllipseWindow {
        dx0: -11.5,
        dy0: -5.25,
        q11: 0.01,
        q12: 0.004,
        q22: 0.03,
        p0: 60.0,
        sx: 0.7,
        sy: -0.4,
    };
    for cols in [0, 1, 7, 8, 9, 16, 23, 29] {
        for rows in [0, 1, 5, 12] {
            let mut want = [0.0f64; 3];
            for r in 0..rows {
                for c in 0..cols {
                    let (dx, dy) = (f64::from(e.dx0) + c as f64, f64::from(e.dy0) + r as f64);
                    let q = f64::from(e.q11) * dx * dx
                        + 2.0 * f64::from(e.q12) * dx * dy
                        + f64::from(e.q22) * dy * dy;
                    let v = f64::from(pixels[r * stride + c]);
                    let bg = f64::from(e.p0) + f64::from(e.sx) * dx + f64::from(e.sy) * dy;
                    if q <= 1.0 {
                        let w = (v - bg).max(0.0);
                        want[0] += w;
                        want[1] += w * dx;
                        want[2] += w * dy;
                    }
                }
            }
            let out = ellipse_window_sums(&pixels, stride, cols, rows, e);
            // Tails read in place (bytes past the window masked) and copied agree.
            if rows > 0 {
                let exact = &pixels[..(rows - 1) * stride + cols];
                assert_eq!(ellipse_window_sums(exact, stride, cols, rows, e), out);
            }
            let portable = ellipse_window_sums_portable(&pixels, stride, cols, rows, e);
            for k in 0..3 {
                assert!(
                    (portable[k] - want[k]).abs() <= 1e-4 * want[k].abs().max(10.0),
                    "portable {cols} x {rows}, sum {k}: {portable:?} vs {want:?}"
                );
                assert!(
                    (out[k] - want[k]).abs() <= 1e-4 * want[k].abs().max(10.0),
                    "{cols} x {rows}, sum {k}: {out:?} vs {want:?}"
                );
            }
        }
    }
}

#[test]
fn kernels_match_scalar() {
    let src: Vec<u8> = (0..3 * 131).map(|i| ((i * 37 + 11) % 251) as u8).collect();
    for c in 0..3 {
        // Under, at and past one or two 32-pixel steps (the overlapping last step).
        for n in [0, 1, 15, 16, 31, 32, 33, 47, 64, 65, 95, 131] {
            let mut d = vec![0; n];
            pick_channel(&src[..3 * n], &mut d, c);
            assert!(
                d.iter().enumerate().all(|(i, &v)| v == src[3 * i + c]),
                "{n}"
            );
            let mut e = vec![0; n];
            pick_channel_portable(&src[..3 * n], &mut e, c);
            assert_eq!(d, e);
        }
    }
    let mut l = vec![0; 131];
    luma601(&src, &mut l, &mut Vec::new());
    for (i, &v) in l.iter().enumerate() {
        let x = 2989 * u32::from(src[3 * i])
            + 5870 * u32::from(src[3 * i + 1])
            + 1140 * u32::from(src[3 * i + 2]);
        assert_eq!(u32::from(v), (x + 5000) / 10000);
    }
    // Lengths below, at and past one 32-byte step, with and without an overlapping tail.
    for n in [0, 1, 31, 32, 33, 63, 64, 65, 100] {
        let (a, b, c) = (&src[..n], &src[1..n + 1], &src[2..n + 2]);
        let mut d = vec![0; n];
        extremum3(a, b, c, &mut d, false);
        assert!((0..n).all(|i| d[i] == a[i].min(b[i]).min(c[i])), "min, {n}");
        extremum3(a, b, c, &mut d, true);
        assert!((0..n).all(|i| d[i] == a[i].max(b[i]).max(c[i])), "max, {n}");
    }
    let mut bytes = vec![0u8; 150];
    above(&src[..150], 120, &mut bytes);
    let mut bits = vec![0u64; 3];
    pack_bits(&bytes, &mut bits);
    for i in 0..150 {
        assert_eq!((bits[i / 64] >> (i % 64)) & 1 == 1, src[i] > 120, "bit {i}");
    }
    for t in [0u8, 1, 120, 200, 254, 255] {
        let mut direct = vec![0u64; 3];
        above_bits(&src[..150], t, &mut direct);
        for i in 0..150 {
            assert_eq!(
                (direct[i / 64] >> (i % 64)) & 1 == 1,
                src[i] > t,
                "t {t} bit {i}"
            );
        }
    }
}
