use deepfoids_env::policy::action_buffers;
use deepfoids_env::{ConfigDirs, Env, Phase, Policy, RandomPolicy, Scene};
fn main() {
    let dirs = ConfigDirs::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../configs"));
    let id = std::env::args().nth(1).unwrap_or("coho_default".into());
    let scene = Scene::load(&dirs, &id, Phase::Pretrain).unwrap();
    let mut env = Env::new(scene, 0);
    let mut pol = RandomPolicy { seed: 0 };
    let mut actions = action_buffers(&env);
    for t in 0..=150u32 {
        if t % 25 == 0 {
            let w = env.world();
            let n = w.len();
            let mut tot = 0usize;
            let mut depth = 0.0;
            for i in 0..n {
                let r = 3.0 * w.bl[i];
                tot += (0..n)
                    .filter(|&j| j != i && w.position[j].distance(w.position[i]) < r)
                    .count();
                depth += -w.position[i].y;
            }
            let term: usize = env
                .output()
                .behaviours
                .iter()
                .map(|b| b.terminated.iter().filter(|x| **x).count())
                .sum();
            println!(
                "tick {t}: mean neighbours {:.1}, mean depth {:.2}, terminated {term}",
                tot as f32 / n as f32,
                depth / n as f32
            );
        }
        pol.act(&env, &mut actions).unwrap();
        env.step(&actions).unwrap();
    }
}
