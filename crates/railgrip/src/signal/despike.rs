//! Hampel despiking of the radar speed (before its low-pass).
//!
//! The Doppler radar's speed "is typically affected by high-frequency noise and spikes
//! corresponding to track irregularities" (seed 002 002_8d8769283f5e9cb6.txt, "Data from test
//! runs"). A linear low-pass smears a 3 m/s single-sample spike into a bump of a few cm/s over
//! a second, which the derivative turns into a deceleration error; a robust filter removes it
//! first.
//!
//! Hampel filter: for each sample x_i, the median m_i and the median absolute deviation
//! MAD_i of the original samples in the centred window [i − k, i + k] (truncated at the ends
//! of the signal); x_i is replaced by m_i when
//!
//! |x_i − m_i| > max(t · 1.4826 · MAD_i, d_min)
//!
//! (1.4826 MAD estimates the standard deviation of Gaussian noise; t is in those units). The
//! floor d_min (m/s) departs from the textbook filter: on a quantised or noise-free trace
//! MAD = 0 and every quantisation step would count as a spike.
//!
//! Cost: a sliding minimum and maximum (monotonic deques, O(1) amortised per sample) bound
//! the median; only where the window spans more than d_min is it sorted for the median and
//! the MAD — near spikes and fast changes, a small share of a radar trace.

use std::collections::VecDeque;

use crate::config::DespikeConfig;

/// [`hampel`] with the pipeline's `[filters.despike]` at `fs` (Hz): the half window
/// `half_window_s` in samples (at least 1). Returns how many samples were replaced.
pub fn despike(x: &mut [f64], d: &DespikeConfig, fs: f64) -> usize {
    let k = ((d.half_window_s * fs).round() as usize).max(1);
    hampel(x, k, d.threshold, d.min_deviation_mps)
}

/// Replaces outliers of `x` in place; returns how many samples were replaced.
/// `half_window` = k in samples (≥ 1), `threshold` = t (> 0), `min_deviation` = d_min (≥ 0,
/// in the unit of `x`). Values must be finite (callers filter finite segments).
pub fn hampel(x: &mut [f64], half_window: usize, threshold: f64, min_deviation: f64) -> usize {
    let n = x.len();
    if n < 3 || half_window == 0 {
        return 0;
    }
    let k = half_window;
    let scale = threshold * 1.482_602_218_505_602;
    // Replacements are applied after the pass: the window always sees the original samples.
    let mut replace: Vec<(usize, f64)> = Vec::new();
    let original: &[f64] = x;
    // Sliding minimum and maximum (monotonic deques of indices). The median lies between
    // them, so when max − min ≤ d_min no sample of the window can be an outlier and the
    // median is not needed: the common case on a smooth trace.
    let mut lo: VecDeque<usize> = VecDeque::with_capacity(2 * k + 2);
    let mut hi: VecDeque<usize> = VecDeque::with_capacity(2 * k + 2);
    let mut w: Vec<f64> = Vec::with_capacity(2 * k + 1);
    for i in 0..n {
        // Window [i − k, i + k] ∩ [0, n).
        let (start, end) = (i.saturating_sub(k), (i + k + 1).min(n));
        let push = if i == 0 {
            0..end
        } else if i + k < n {
            end - 1..end
        } else {
            end..end
        };
        for j in push {
            while lo.back().is_some_and(|&b| original[b] >= original[j]) {
                lo.pop_back();
            }
            lo.push_back(j);
            while hi.back().is_some_and(|&b| original[b] <= original[j]) {
                hi.pop_back();
            }
            hi.push_back(j);
        }
        while lo.front().is_some_and(|&f| f < start) {
            lo.pop_front();
        }
        while hi.front().is_some_and(|&f| f < start) {
            hi.pop_front();
        }
        let (min, max) = (original[lo[0]], original[hi[0]]);
        if max - min <= min_deviation {
            continue;
        }
        w.clear();
        w.extend_from_slice(&original[start..end]);
        w.sort_unstable_by(f64::total_cmp);
        let m = w.len();
        let med = if m % 2 == 1 {
            w[m / 2]
        } else {
            0.5 * (w[m / 2 - 1] + w[m / 2])
        };
        let d = (original[i] - med).abs();
        if d > min_deviation && d > scale * mad(&w, med) {
            replace.push((i, med));
        }
    }
    for &(i, med) in &replace {
        x[i] = med;
    }
    replace.len()
}

/// Median of |w_j − med| for sorted `w`: merges the distances below and above the median,
/// both increasing outward, up to the middle rank.
fn mad(w: &[f64], med: f64) -> f64 {
    let m = w.len();
    let (r1, r2) = ((m - 1) / 2, m / 2);
    let c = w.partition_point(|&a| a < med);
    let (mut lo, mut hi) = (c, c); // next left is w[lo − 1], next right is w[hi]
    let mut at_r1 = 0.0;
    for rank in 0..=r2 {
        let dl = if lo > 0 {
            med - w[lo - 1]
        } else {
            f64::INFINITY
        };
        let dh = if hi < m { w[hi] - med } else { f64::INFINITY };
        let d = if dl <= dh {
            lo -= 1;
            dl
        } else {
            hi += 1;
            dh
        };
        if rank == r1 {
            at_r1 = d;
        }
        if rank == r2 {
            return 0.5 * (at_r1 + d);
        }
    }
    unreachable!("rank r2 < m is always reached")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn brute_mad(w: &[f64]) -> f64 {
        let med = median(w);
        median(&w.iter().map(|v| (v - med).abs()).collect::<Vec<_>>())
    }
    fn median(v: &[f64]) -> f64 {
        let mut s = v.to_vec();
        s.sort_by(f64::total_cmp);
        let m = s.len();
        if m % 2 == 1 {
            s[m / 2]
        } else {
            0.5 * (s[m / 2 - 1] + s[m / 2])
        }
    }

    #[test]
    fn mad_matches_brute_force() {
        let mut seed = 7u64;
        for len in 1..30 {
            let mut w: Vec<f64> = (0..len)
                .map(|_| {
                    seed = seed
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    ((seed >> 33) % 17) as f64 * 0.25
                })
                .collect();
            w.sort_by(f64::total_cmp);
            let med = median(&w);
            assert_eq!(mad(&w, med), brute_mad(&w), "{w:?}");
        }
    }

    #[test]
    fn removes_single_spikes_and_keeps_a_smooth_ramp() {
        let mut x: Vec<f64> = (0..400)
            .map(|i| 30.0 - 0.002 * i as f64 + 0.01 * ((i * 7919) % 13) as f64 / 13.0)
            .collect();
        let clean = x.clone();
        x[100] += 3.0;
        x[250] -= 2.5;
        x[0] += 4.0;
        x[399] -= 4.0;
        let n = hampel(&mut x, 10, 3.0, 0.1);
        assert_eq!(n, 4);
        for (i, (a, b)) in x.iter().zip(&clean).enumerate() {
            assert!((a - b).abs() < 0.05, "{i}: {a} vs {b}");
        }
    }

    #[test]
    fn flat_quantised_trace_is_left_alone() {
        let mut x: Vec<f64> = (0..200)
            .map(|i| if i % 17 == 0 { 10.001 } else { 10.0 })
            .collect();
        let before = x.clone();
        assert_eq!(hampel(&mut x, 10, 3.0, 0.1), 0);
        assert_eq!(x, before);
    }

    #[test]
    fn matches_brute_force_hampel() {
        let mut seed = 11u64;
        let mut x: Vec<f64> = (0..300)
            .map(|i| {
                seed = seed
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let u = (seed >> 11) as f64 / (1u64 << 53) as f64;
                let spike = if (seed >> 7).is_multiple_of(23) {
                    2.0
                } else {
                    0.0
                };
                0.01 * i as f64 + 0.1 * u + spike
            })
            .collect();
        let orig = x.clone();
        let k = 6;
        let mut expect = orig.clone();
        for i in 0..orig.len() {
            let win = &orig[i.saturating_sub(k)..(i + k + 1).min(orig.len())];
            let med = median(win);
            let d = (orig[i] - med).abs();
            if d > 0.05 && d > 2.0 * 1.482_602_218_505_602 * brute_mad(win) {
                expect[i] = med;
            }
        }
        hampel(&mut x, k, 2.0, 0.05);
        assert_eq!(x, expect);
    }
}
