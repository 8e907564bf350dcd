//! Light and temperature responses inside the env, and the decision interval.
mod common;
use common::*;
use deepfoids_env::sun::SunPlace;
use glam::Vec3;

/// Coho at Onmaehama at solar noon (I0 = 519.69 PAR, a = 1.5, T_surf 8.3 °C),
/// preferences set to [3, 7] PAR:
/// * 1 m: I = 115.958 → Δv_light = −(115.958 − 7)/(1000 − 7) = −0.109726;
///   T = 7.3 °C → Δv_temp = (8 − 7.3)/(8 + 60) = 0.0102941;
/// * 4 m: I = 1.28823 → Δv_light = (3 − 1.28823)/23 = 0.0744248;
/// * 0.2 m: T = 8.1 °C is preferred → Δv_temp = 0.
#[test]
fn responses_at_chosen_depths_at_noon() {
    let mut s = scene("coho_default", 3);
    let site = &s.site;
    let place = SunPlace {
        latitude_deg: site.latitude_deg as f64,
        longitude_deg: site.longitude_deg as f64,
        utc_offset_hours: site.utc_offset_hours as f64,
    };
    s.clock.start_hours = place.solar_noon_hours(s.clock.year, s.clock.month, s.clock.day) as f32;
    let mut env = calm_env(s);
    assert!(
        close(env.surface_light(), 519.69, 0.01),
        "{}",
        env.surface_light()
    );
    for (i, depth) in [1.0f32, 4.0, 0.2].into_iter().enumerate() {
        common::place(&mut env, i, Vec3::new(0.0, -depth, 0.0), Vec3::Z, 0.2);
        env.world_mut().light_pref[i] = [3.0, 7.0];
    }
    let (l1, t1) = env.vertical_response(0);
    assert!(
        close(l1, -0.109726, 2e-5) && close(t1, 0.0102941, 1e-6),
        "{l1} {t1}"
    );
    let (l4, t4) = env.vertical_response(1);
    assert!(
        close(l4, 0.0744248, 2e-5) && close(t4, 0.0102941, 1e-6),
        "{l4} {t4}"
    );
    let (_, t02) = env.vertical_response(2);
    assert_eq!(t02, 0.0);
}

/// At 22:00 the sun is down: I0 = 0, every fish is pulled up by I_lpref/(I_lpref + 20).
#[test]
fn at_night_light_is_zero_and_fish_rise() {
    let mut s = scene("seabream_default", 1);
    s.clock.start_hours = 22.0;
    let env = deepfoids_env::Env::new(s, 1);
    assert_eq!(env.surface_light(), 0.0);
    let (l, _) = env.vertical_response(0);
    assert!(close(l, 5.75 / 25.75, 1e-6));
}

/// Eq. 4.4 in motion: a seabream level at the speed floor (0.2 BL/s) with only
/// a light push gains Δv_light·BL over one decision (k = 5 steps of
/// Δv_light·BL/5), straight up: v = (0, 5.75/25.75, 0.2)·BL.
#[test]
fn vertical_push_accumulates_over_one_decision() {
    let mut s = scene("seabream_default", 1);
    s.clock.start_hours = 22.0; // night: Δv_light = 5.75/25.75 BL/s up
    let mut env = deepfoids_env::Env::new(s, 1);
    common::place(&mut env, 0, Vec3::new(0.0, -1.5, 0.0), Vec3::Z, 0.2);
    env.observe_now();
    let bl = env.world().bl[0];
    env.step(&zeros(&env)).unwrap();
    let v = env.world().velocity(0);
    let expected = 5.75 / 25.75 * bl;
    assert!(
        close(v.y, expected, 1e-4) && v.x.abs() < 1e-6 && close(v.z, 0.2 * bl, 1e-5),
        "{v} vs {expected}"
    );
}

/// Regression (issue 11, item 3): the light and temperature responses are
/// computed once per decision, at the depth of the decision, and spread over
/// its k steps (Eq. 4.4), not re-evaluated at every physics step.
///
/// Three species at Nishiki at 22:00 (I0 = 0, 22 °C at the surface); a coho
/// (k = 10, two ticks of 5 steps) with light band [3, 7] PAR decides level at
/// the floor 0.2 BL/s and 0.2 m deep, with a zero action:
/// Δv_light = (3 − 0)/(3 + 20) = 0.1304348 up; T = 21.8 °C, Δv_temp =
/// −(21.8 − 9)/(80 − 9) = −0.1802817; sum −0.0498469 BL/s. Moved to 2 m after
/// the first tick (where the sum would be 0.1304348 − 12/71 = −0.0385793), it
/// still ends the decision with v_y = −0.0498469·BL (per-step re-evaluation
/// would give the mean, −0.0442131·BL), and v_z = 0.2·BL.
#[test]
fn vertical_responses_are_computed_once_per_decision() {
    let mut s =
        deepfoids_env::Scene::load(&dirs(), "three_species", deepfoids_env::Phase::Pretrain)
            .unwrap();
    s.clock.start_hours = 22.0;
    let mut env = calm_env(s);
    env.world_mut().light_pref[0] = [3.0, 7.0];
    common::place(&mut env, 0, Vec3::new(0.0, -0.2, 0.0), Vec3::Z, 0.2);
    env.observe_now();
    let bl = env.world().bl[0];
    let actions = zeros(&env);
    env.step(&actions).unwrap();
    assert!(!env.awaiting(0), "coho decide every second tick");
    env.world_mut().position[0].y = -2.0;
    env.step(&actions).unwrap();
    let v = env.world().velocity(0);
    assert!(
        close(v.y, -0.0498469 * bl, 2e-6) && close(v.z, 0.2 * bl, 2e-6) && v.x.abs() < 1e-6,
        "{v} (BL {bl}): expected v_y = {}",
        -0.0498469 * bl
    );
}

/// k = floor(dt_res / dt_sim) at 20 ms: coho 10, yellowtail and seabream 5; in
/// the three-species scene a tick is 5 steps and coho decide every second tick.
#[test]
fn decision_intervals() {
    for (id, k) in [
        ("coho_default", 10),
        ("yellowtail_default", 5),
        ("seabream_default", 5),
    ] {
        let env = deepfoids_env::Env::new(scene(id, 2), 0);
        assert_eq!(env.behaviours()[0].steps_per_decision, k, "{id}");
    }
    let s = deepfoids_env::Scene::load(&dirs(), "three_species", deepfoids_env::Phase::Pretrain)
        .unwrap();
    let mut env = deepfoids_env::Env::new(s, 0);
    assert_eq!(env.tick_steps(), 5);
    let ks: Vec<(usize, u64)> = env
        .behaviours()
        .iter()
        .map(|b| (b.steps_per_decision, b.period_ticks))
        .collect();
    assert_eq!(ks, vec![(10, 2), (5, 1), (5, 1)]);
    let actions = zeros(&env);
    let out = env.step(&actions).unwrap();
    assert_eq!(
        out.behaviours.iter().map(|b| b.decided).collect::<Vec<_>>(),
        vec![false, true, true]
    );
    assert!(!env.awaiting(0) && env.awaiting(1));
    // Coho's actions may be omitted when it is not awaiting.
    let partial = vec![vec![], actions[1].clone(), actions[2].clone()];
    let out = env.step(&partial).unwrap();
    assert_eq!(
        out.behaviours.iter().map(|b| b.decided).collect::<Vec<_>>(),
        vec![true, true, true]
    );
    assert!((out.time - 0.2).abs() < 1e-6);
}

/// Regression (issue 11, item 4): the mixed-size coho scenes are at Onmaehama,
/// the coho farm. At 11:00 in mid-March, 2 m deep, the water is 8.3 − 1 = 7.3 °C:
/// Δv_temp = (8 − 7.3)/(8 + 60) = 0.0102941 up (at Nishiki it would be
/// −(21 − 9)/(80 − 9) = −0.1690141, down).
#[test]
fn mixed_coho_scenes_are_at_the_coho_farm() {
    for id in ["coho_mixed", "coho_mixed_small_cage"] {
        let s = scene(id, 3);
        assert_eq!(s.site.name, "onmaehama", "{id}");
        assert_eq!((s.clock.month, s.clock.day), (3, 15), "{id}");
        let mut env = calm_env(s);
        common::place(&mut env, 0, Vec3::new(0.0, -2.0, 0.0), Vec3::Z, 0.2);
        let (_, temp) = env.vertical_response(0);
        assert!(close(temp, 0.0102941, 1e-6), "{id}: {temp}");
    }
}
