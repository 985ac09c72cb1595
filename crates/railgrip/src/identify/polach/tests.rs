//! Unit tests of the Polach fits' internals (law, problem, temperature basis).

use super::law::{
    law_params, mu_and_gradient, mu_only, to_natural, to_unconstrained, with_patch, Sample, LOWER,
    UPPER,
};
use super::problem::{basis_at, constant_nodes, lagrange, temperature_nodes, Group, PolachProblem};
use super::temperature::{monomials, poly_mul};
use crate::contact::polach::{horner, ContactPatch};
use crate::identify::lm::LeastSquares;

#[test]
fn reparametrisation_round_trips_and_respects_bounds() {
    for (i, x) in [(0, 0.3), (1, 0.4), (2, 0.2), (3, 0.3), (4, 0.5), (2, 40.0)] {
        let (back, dx) = to_natural(i, to_unconstrained(i, x));
        assert!((back - x).abs() < 1e-12 * x.max(1.0), "{i}: {back} vs {x}");
        // dx/dp against a central difference.
        let p = to_unconstrained(i, x);
        let h = 1e-6;
        let fd = (to_natural(i, p + h).0 - to_natural(i, p - h).0) / (2.0 * h);
        assert!(
            (dx - fd).abs() < 1e-6 * fd.abs().max(1e-12),
            "{i}: {dx} vs {fd}"
        );
    }
    for (i, p) in [(0, 60.0), (1, -60.0), (2, 60.0), (3, 60.0), (4, 60.0)] {
        let x = to_natural(i, p).0;
        assert!(x >= LOWER[i] && x <= UPPER[i], "{i}: {x}");
    }
}

/// The contact patch of the unit tests (also the fit module's).
pub(super) fn patch() -> ContactPatch {
    ContactPatch {
        a_m: 0.0061,
        b_m: 0.0045,
        g_pa: 8.0e10,
        c11: 4.1,
        c22: 3.6,
    }
}

proptest::proptest! {
    /// The analytic μ is the contact library's, and its gradient matches central
    /// differences, over the law's whole domain.
    #[test]
    fn analytic_gradient_matches_the_law_and_finite_differences(
        mu0 in 0.02f64..1.0, a in 0.01f64..0.99, b in 0.01f64..5.0,
        k_a in 0.01f64..1.0, rho in 0.01f64..1.0,
        dv in 0.001f64..8.0, v in 1.0f64..90.0,
    ) {
        let p = patch();
        let q = 80_000.0;
        let x = [mu0, a, b, k_a, rho];
        let s = with_patch(vec![Sample { q_n: q, v, dv, mu: 0.0, cs: f64::NAN }], &p, None)[0];
        let (f, g) = mu_and_gradient(&x, &s);
        proptest::prop_assert_eq!(f.to_bits(), mu_only(&x, &s).to_bits());
        let law = crate::contact::polach::polach(&p, &law_params(&x), q, v, dv, 0.0).unwrap();
        proptest::prop_assert!((f - law.fx_n / q).abs() <= 1e-14 * f.abs().max(1e-3), "{} vs {}", f, law.fx_n / q);
        for i in 0..5 {
            let h = 1e-6 * x[i];
            let (mut up, mut dn) = (x, x);
            up[i] += h;
            dn[i] -= h;
            let fd = (mu_only(&up, &s) - mu_only(&dn, &s)) / (2.0 * h);
            // Truncation O(h²) relative, plus the rounding of the difference quotient,
            // a few ulps of f over h.
            let tol = 1e-6 * (g[i].abs() + fd.abs()) + 16.0 * f64::EPSILON * f.abs() / h;
            proptest::prop_assert!((g[i] - fd).abs() <= tol, "param {}: {} vs {}", i, g[i], fd);
        }
    }
}

/// Samples over three temperature groups for the problem tests.
fn grouped_samples() -> (Vec<Sample>, Vec<(f64, std::ops::Range<usize>)>) {
    let mut rng = crate::rng::Rng::new(3);
    let mut s = Vec::new();
    let mut ranges = Vec::new();
    for (g, t) in [-20.0, 5.0, 30.0].iter().enumerate() {
        let from = s.len();
        for _ in 0..200 {
            let dv = 0.01 + 3.0 * rng.uniform();
            s.push(Sample {
                q_n: 80_000.0,
                v: 5.0 + 30.0 * rng.uniform(),
                dv,
                mu: 0.08 + 0.01 * g as f64 + 0.005 * rng.normal(),
                cs: f64::NAN,
            });
        }
        ranges.push((*t, from..s.len()));
    }
    (with_patch(s, &patch(), None), ranges)
}

fn groups_for(degrees: [usize; 5], ranges: &[(f64, std::ops::Range<usize>)]) -> Vec<Group> {
    ranges
        .iter()
        .map(|(t, r)| Group {
            range: r.clone(),
            basis: basis_at(degrees, -20.0, 30.0, *t),
        })
        .collect()
}

/// Jᵀr of the temperature-law problem (Lagrange nodes, the logistic chain, k_S held for
/// a profile) is the gradient of SSE/2 in θ, by central differences; and with every degree
/// 0 the grouped problem is the plain one.
#[test]
fn grouped_problems_have_the_gradient_of_their_cost() {
    let (s, ranges) = grouped_samples();
    let x = [0.1, 0.4, 0.5, 0.2, 0.4];
    for (degrees, fixed, ks) in [
        ([1, 0, 0, 2, 1], [None; 5], None),
        ([2, 0, 0, 0, 0], [None, None, Some(0.5), None, None], None),
        ([0; 5], [None; 5], Some(0.07)),
    ] {
        let problem = PolachProblem::new(&s, groups_for(degrees, &ranges), degrees, fixed, ks);
        let mut nodes = constant_nodes(&x);
        // Distinct node values, so that the law does vary with temperature.
        nodes[0][1] = 0.12;
        nodes[3][2] = 0.25;
        let theta = problem.theta(&nodes);
        let ne = problem.normal_equations(&theta);
        assert!((ne.sse - problem.sse(&theta)).abs() < 1e-12 * ne.sse);
        for k in 0..theta.len() {
            let h = 1e-6;
            let (mut up, mut dn) = (theta.clone(), theta.clone());
            up[k] += h;
            dn[k] -= h;
            let fd = (problem.sse(&up) - problem.sse(&dn)) / (4.0 * h);
            assert!(
                (ne.jtr[k] - fd).abs() <= 1e-6 * fd.abs().max(1e-6),
                "{degrees:?} coordinate {k}: {} vs {fd}",
                ne.jtr[k]
            );
        }
    }
    let plain = PolachProblem::plain(&s, [None; 5], None);
    let grouped = PolachProblem::new(&s, groups_for([0; 5], &ranges), [0; 5], [None; 5], None);
    let theta = plain.theta(&constant_nodes(&x));
    assert_eq!(
        plain.normal_equations(&theta).jtr,
        grouped.normal_equations(&theta).jtr
    );
}

#[test]
fn lagrange_nodes_expand_to_the_polynomial_through_them() {
    let c = [0.1, 0.002, -1e-5, 3e-8];
    for d in 1..=3 {
        // A polynomial of degree d, which d + 1 nodes determine.
        let f = |t: f64| horner(&c[..=d], t);
        let nodes = temperature_nodes(d, -20.0, 35.0);
        let values: Vec<f64> = nodes.iter().map(|t| f(*t)).collect();
        let c = monomials(&nodes, &values);
        for t in [-20.0, -3.0, 0.0, 12.5, 35.0] {
            assert!((horner(&c, t) - f(t)).abs() < 1e-14, "degree {d} at {t}");
            let b = lagrange(&nodes, t);
            let v: f64 = values.iter().zip(b).map(|(v, b)| v * b).sum();
            assert!((v - f(t)).abs() < 1e-14, "basis, degree {d} at {t}");
        }
    }
    assert_eq!(poly_mul(&[1.0, 2.0], &[3.0, 0.5]), vec![3.0, 6.5, 1.0]);
}

/// The block evaluation gives every sample the bits of the one-sample law, on every lane
/// width this CPU has (vector lanes and the f64 tail alike), with and without the gradient.
#[test]
fn the_law_on_vector_lanes_has_the_one_sample_laws_bits() {
    use super::block::{LawBlock, BLOCK};
    let p = patch();
    let mut rng = crate::rng::Rng::new(11);
    // 61 samples: whole vectors and a tail; slips from creep to 8 m/s.
    let samples: Vec<Sample> = (0..61)
        .map(|i| Sample {
            q_n: 80_000.0,
            v: 1.0 + 80.0 * rng.uniform(),
            dv: if i == 0 {
                1e-6
            } else {
                8.0 * rng.uniform() + 1e-4
            },
            mu: 0.0,
            cs: f64::NAN,
        })
        .collect();
    let samples = with_patch(samples, &p, None);
    assert!(samples.len() < BLOCK);
    for x in [
        [0.3, 0.4, 0.6, 0.3, 0.5],
        [0.05, 0.9, 40.0, 1.0, 1e-4],
        [1.2, 0.01, 0.001, 1e-3, 1.0],
    ] {
        for isa in crate::simd::Isa::all_available() {
            for grad in [false, true] {
                let mut blk = LawBlock::new();
                blk.load(&samples, x[0], |_| (1.0, [0.0; 3], true));
                blk.eval(isa, [x[1], x[2], x[3], x[4]], grad);
                for (i, s) in samples.iter().enumerate() {
                    let (f, g) = mu_and_gradient(&x, s);
                    assert_eq!(blk.f[i].to_bits(), f.to_bits(), "{isa:?} sample {i}");
                    if grad {
                        for (k, gk) in g.iter().enumerate() {
                            assert_eq!(blk.grad[k][i].to_bits(), gk.to_bits(), "{isa:?} {i} {k}");
                        }
                    }
                }
            }
        }
    }
}

/// The Gram accumulation against plain sums, and the same bits on every lane width this CPU
/// has: over several panels with a last one whose length is not a multiple of four (2 503
/// samples: its padding must clear the earlier panel's values), and below one vector (3).
#[test]
fn the_gram_panels_sum_jtj_and_jtr_and_give_the_same_bits_on_every_cpu_path() {
    for n in [2503, 3] {
        gram_against_plain_sums(n);
    }
}

fn gram_against_plain_sums(n: usize) {
    use super::block::Gram;
    let mut rng = crate::rng::Rng::new(5);
    let k = 7;
    let rows: Vec<(Vec<f64>, f64)> = (0..n)
        .map(|_| {
            let row: Vec<f64> = (0..k).map(|_| rng.uniform() * 2.0 - 1.0).collect();
            (row, rng.uniform() - 0.5)
        })
        .collect();
    let mut naive_jtj = vec![0.0; k * k];
    let mut naive_jtr = vec![0.0; k];
    for (row, r) in &rows {
        for a in 0..k {
            naive_jtr[a] += row[a] * r;
            for b in 0..k {
                naive_jtj[a * k + b] += row[a] * row[b];
            }
        }
    }
    let mut first: Option<(Vec<f64>, Vec<f64>)> = None;
    for isa in crate::simd::Isa::all_available() {
        let mut g = Gram::new(k, rows.len(), isa);
        for (row, r) in &rows {
            g.push(row, *r);
        }
        let (jtj, jtr) = g.finish();
        for (x, y) in jtj.iter().zip(&naive_jtj).chain(jtr.iter().zip(&naive_jtr)) {
            assert!(
                (x - y).abs() <= 1e-12 * y.abs().max(1.0),
                "{isa:?}: {x} vs {y}"
            );
        }
        for a in 0..k {
            for b in 0..k {
                assert_eq!(jtj[a * k + b].to_bits(), jtj[b * k + a].to_bits());
            }
        }
        match &first {
            None => first = Some((jtj, jtr)),
            Some((j0, r0)) => {
                let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&jtj), bits(j0), "{isa:?}");
                assert_eq!(bits(&jtr), bits(r0), "{isa:?}");
            }
        }
    }
}

/// The SSE LM takes at a trial step is [`PolachProblem::sse_nodes`]'s, bit for bit, and the
/// normal equations it keeps beside it are the ones computed afresh: right after the SSE at
/// their θ, after an SSE at another θ, and asked for twice (the second time computed again).
#[test]
fn normal_equations_kept_from_the_sse_are_the_fresh_ones_bit_for_bit() {
    let (s, ranges) = grouped_samples();
    let degrees = [1, 0, 0, 2, 1];
    let problem = || PolachProblem::new(&s, groups_for(degrees, &ranges), degrees, [None; 5], None);
    let mut nodes = constant_nodes(&[0.1, 0.4, 0.5, 0.2, 0.4]);
    nodes[0][1] = 0.12;
    nodes[3][2] = 0.25;
    let p = problem();
    let theta = p.theta(&nodes);
    let other: Vec<f64> = theta.iter().map(|t| t + 0.01).collect();
    let bits = |ne: &crate::identify::lm::NormalEquations| ne.bits();
    let fresh = problem().normal_equations(&theta);
    assert_eq!(
        p.sse(&theta).to_bits(),
        p.sse_nodes(&p.nodes(&theta).0).to_bits()
    );
    assert_eq!(bits(&p.normal_equations(&theta)), bits(&fresh), "kept");
    assert_eq!(
        bits(&p.normal_equations(&theta)),
        bits(&fresh),
        "asked again"
    );
    p.sse(&theta);
    p.sse(&other);
    assert_eq!(
        bits(&p.normal_equations(&theta)),
        bits(&fresh),
        "after another θ"
    );
    assert_eq!(
        bits(&p.normal_equations(&other)),
        bits(&problem().normal_equations(&other)),
        "the other θ, computed again (its kept ones were taken by the θ before)"
    );
}
