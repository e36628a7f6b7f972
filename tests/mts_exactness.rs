//! Exactness oracles of the multiple-time-step methods: what they must reproduce bit for
//! bit, and the symplecticity of their one-step maps (GSS98 section 5).

mod common;

use common::{MTS_METHODS, SLOW_MIDDLE, integrate, method, scene, three_spring};

#[test]
fn without_slow_forces_every_method_is_the_reduced_verlet_trajectory() {
    // No slow force: the kicks vanish and every method is inner Verlet with dt = h/K.
    let (h, inner, steps) = (0.4, 8, 25);
    let dt = h / inner as f64;
    let mut reference = scene(&three_spring("", "fast"));
    let (q_ref, p_ref) = integrate(
        &mut reference,
        method("verlet", dt, None).as_mut(),
        inner * steps,
    );
    for name in MTS_METHODS {
        let mut mts = scene(&three_spring("", "fast"));
        let (q, p) = integrate(&mut mts, method(name, h, Some(inner)).as_mut(), steps);
        assert_eq!(q, q_ref, "{name}: positions differ from reduced Verlet");
        assert_eq!(p, p_ref, "{name}: momenta differ from reduced Verlet");
    }
}

#[test]
fn one_level_r_respa_is_velocity_verlet_bit_for_bit() {
    // The oracle of openmm PR#1618: with every term in one group and one inner step,
    // r-RESPA is velocity Verlet — the same numbers, not merely close ones.
    let h = 0.02;
    for group in ["fast", "slow"] {
        let middle = SLOW_MIDDLE.replace("\"slow\"", &format!("\"{group}\""));
        let mut reference = scene(&three_spring(&middle, group));
        let (q_ref, p_ref) = integrate(&mut reference, method("verlet", h, None).as_mut(), 500);
        for name in ["impulse", "long-average"] {
            if name == "long-average" && group == "fast" {
                continue; // no slow force: covered by the test above
            }
            let mut mts = scene(&three_spring(&middle, group));
            let (q, p) = integrate(&mut mts, method(name, h, Some(1)).as_mut(), 500);
            if name == "impulse" {
                assert_eq!(q, q_ref, "impulse, all terms {group}");
                assert_eq!(p, p_ref, "impulse, all terms {group}");
            } else {
                // LongAverage with an empty fast level averages a free particle at rest:
                // A(q) = q and A_q = I up to the trapezoid sum, so it is Verlet to round-off.
                let error = common::max_abs_difference(&q, &q_ref);
                assert!(error < 1e-12, "long-average, all slow: {error:e}");
            }
        }
    }
}

#[test]
fn recursive_r_respa_with_unit_level_steps_is_verlet() {
    // Three levels, each taking one step of the level below: every force is applied at
    // every step, as in Verlet; the kicks come one level at a time, so the sums round
    // differently and agreement is to round-off, not bit for bit.
    let text = three_spring(SLOW_MIDDLE, "fast").replace(
        "group = \"slow\"",
        "level = 1\n[[terms]]\ntype = \"lennard-jones\"\nepsilon = 0.01\nsigma = 0.5\nlevel = 2",
    );
    let mut reference = scene(&text);
    assert_eq!(reference.system.forces.n_levels(), 3);
    let (q_ref, _) = integrate(&mut reference, method("verlet", 0.01, None).as_mut(), 300);
    let mut settings = longstep::settings::MethodSettings::new("impulse", 0.01);
    settings.level_steps = Some(vec![1, 1]);
    let mut impulse = longstep::integrators::build(&settings, &mut Vec::new()).unwrap();
    let mut mts = scene(&text);
    let (q, _) = integrate(&mut mts, impulse.as_mut(), 300);
    let error = common::max_abs_difference(&q, &q_ref);
    assert!(
        error < 1e-12,
        "3-level r-RESPA with unit steps vs Verlet: {error:e}"
    );
}

/// `Jᵀ Ω J − Ω` for the one-step map of `name`, J by a fourth-order central difference.
fn symplecticity_defect(name: &str, h: f64, inner: usize) -> (f64, f64) {
    let text = three_spring(SLOW_MIDDLE, "fast");
    common::symplecticity_defect(&text, &|| method(name, h, Some(inner)))
}

#[test]
fn one_step_maps_are_symplectic_on_the_nonlinear_three_spring_system() {
    // A conservative slow force makes every method of the family symplectic: the mollified
    // impulse is the gradient of U(A(q)) (GSS98 section 5). The finite-difference Jacobian
    // is accurate to ~1e-11 here (‖J‖ ~ 10), so a defect below 1e-10 is what symplecticity
    // predicts, and a non-symplectic method (an impulse A_qᵀ F(q) without the average, say)
    // is off by O(h |F_q|) ~ 1e-2.
    for name in MTS_METHODS {
        let (defect, size) = symplecticity_defect(name, 0.3, 12);
        eprintln!("{name}: |JᵀΩJ − Ω| = {defect:e}, |J| = {size:.2}");
        assert!(
            defect < 1e-10,
            "{name}: |JᵀΩJ − Ω| = {defect:e} (|J| = {size:.1})"
        );
    }
}
