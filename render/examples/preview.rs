//! Render a few frames of a scene (random actions) under several conditions
//! and time the renderer: `cargo run --release -p deepfoids-render --example
//! preview -- <scene> <out dir> [width height]`.

use deepfoids_env::policy::action_buffers;
use deepfoids_env::{ConfigDirs, Env, Phase, Policy, RandomPolicy, Scene};
use deepfoids_render::dataset::encode_mask;
use deepfoids_render::setup::{TailPhases, place_camera, poses, species_meshes};
use deepfoids_render::{CameraKind, ClipParams, RenderConfig, Renderer, WaterParams};
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let scene_id = args.get(1).map(String::as_str).unwrap_or("coho_default");
    let out = std::path::PathBuf::from(args.get(2).map(String::as_str).unwrap_or("/tmp/preview"));
    let w: u32 = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(1280);
    let h: u32 = args.get(4).and_then(|s| s.parse().ok()).unwrap_or(720);
    std::fs::create_dir_all(&out).unwrap();
    let dirs = ConfigDirs::discover();
    let scene = Scene::load(&dirs, scene_id, Phase::Pretrain).unwrap();
    let mut env = Env::new(scene.clone(), 1);
    let mut policy = RandomPolicy { seed: 1 };
    let mut actions = action_buffers(&env);
    let mut phases = TailPhases::new(env.world().len(), 1);
    for _ in 0..50 {
        policy.act(&env, &mut actions).unwrap();
        env.step(&actions).unwrap();
        phases.advance(env.world(), env.tick_seconds() as f32);
    }
    let renderer = Renderer::new(
        RenderConfig::default(),
        species_meshes(&scene),
        Renderer::faces_of(&scene.cage()),
    );
    let fish = poses(env.world(), &phases);
    let turbid = WaterParams {
        chlorophyll: 8.0,
        sediment: 4.0,
        small_particles: 1.0,
        large_particles: 1.0,
    };
    let clear = WaterParams {
        chlorophyll: 0.2,
        sediment: 0.0,
        small_particles: 0.01,
        large_particles: 0.02,
    };
    for (name, kind, hours, water) in [
        ("side_noon", CameraKind::Side, 11.7, WaterParams::default()),
        (
            "side_evening",
            CameraKind::Side,
            17.3,
            WaterParams::default(),
        ),
        ("side_clear", CameraKind::Side, 11.7, clear),
        ("side_turbid", CameraKind::Side, 11.7, turbid),
        (
            "bottom_noon",
            CameraKind::BottomFisheye,
            11.7,
            WaterParams::default(),
        ),
        (
            "bottom_evening",
            CameraKind::BottomFisheye,
            17.3,
            WaterParams::default(),
        ),
        (
            "sidefish_noon",
            CameraKind::SideFisheye,
            11.7,
            WaterParams::default(),
        ),
    ] {
        let mut clip = ClipParams::from_scene(&scene, 0, 1, kind);
        clip.water = water;
        let cond = clip.conditions(&scene, hours, true);
        let cam = place_camera(&scene.cage(), &clip.camera, w, h);
        let t = Instant::now();
        let reps = 5;
        let mut frame = None;
        for _ in 0..reps {
            frame = Some(renderer.render(&fish, &cam, &cond));
        }
        let dt = t.elapsed().as_secs_f64() / reps as f64;
        let frame = frame.unwrap();
        let t2 = Instant::now();
        let mask = encode_mask(&frame).unwrap();
        let enc = t2.elapsed().as_secs_f64();
        image::save_buffer(
            out.join(format!("{name}.png")),
            &frame.rgb,
            w,
            h,
            image::ExtendedColorType::Rgb8,
        )
        .unwrap();
        std::fs::write(out.join(format!("{name}_mask.png")), mask).unwrap();
        // A false-colour view of the mask for looking at.
        let vis: Vec<u8> = frame
            .ids
            .iter()
            .flat_map(|&id| {
                if id == 0 {
                    [0, 0, 0]
                } else {
                    let k = id as u32 * 2654435761;
                    [
                        (k >> 24) as u8 | 64,
                        (k >> 16) as u8 | 64,
                        (k >> 8) as u8 | 64,
                    ]
                }
            })
            .collect();
        image::save_buffer(
            out.join(format!("{name}_maskvis.png")),
            &vis,
            w,
            h,
            image::ExtendedColorType::Rgb8,
        )
        .unwrap();
        println!(
            "{name}: {:.1} ms/frame render+labels ({:.2} fps), mask encode {:.1} ms, {} fish in the frame, {} in view, {} detectable, sun {:.1}°, gain {:.3e}",
            dt * 1e3,
            1.0 / dt,
            enc * 1e3,
            frame.fish.len(),
            frame.in_view_count(),
            frame.visible_count(),
            cond.light.sun_elevation_deg,
            frame.gain
        );
    }
}
