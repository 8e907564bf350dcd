//! `deepfoids._core`: the Rust side of the Python package.
//!
//! The Python classes (`deepfoids.BatchEnv`, `deepfoids.parallel_env`,
//! `deepfoids.load_policy`) are thin layers over two classes defined here:
//!
//! * [`Core`] — one [`Env`] and the agent-major buffers the Python side reads:
//!   `grid [N, 18, 20, 34]`, `vector [N, 6]`, `reward [N]`, `terms [N, 7]`,
//!   `terminated [N]`, `truncated [N]`, `decided [N]`. Python receives them as
//!   numpy arrays that *view* this memory (no copy per step), and [`Core::step`]
//!   overwrites them in place with the GIL released.
//! * [`OnnxModel`] — an exported policy run by tract (`deepfoids_onnx`'s runtime,
//!   built without the Burn exporter).
//!
//! # The grid buffer
//!
//! The stacked grids are 49 kB per agent (49 MB for coho_default's 1,000 fish);
//! copying them each step costs about as much as the step itself. So a scene with
//! one behaviour hands out a view of the environment's own output buffer, which
//! [`Env::step`] rewrites in place and never reallocates (its contract: "step
//! allocates nothing"); the pointer is checked after every step, and a moved
//! buffer is an error, never a dangling view. A scene with several behaviours
//! keeps its own contiguous buffer, and the deciding behaviours' rows are copied
//! into it (in parallel) after each step.
//!
//! # Episodes
//!
//! A `Core` is one school: its seed draws the fish's traits and poses. A new
//! episode with another seed is a new `Core` ([`Core::reseeded`]), so views
//! handed out earlier keep their own (old) core alive and valid.

use deepfoids_env::{ConfigDirs, Env, N_TERMS, Phase, Scene, TERM_NAMES, VECTOR_OBS};
use deepfoids_onnx::OnnxPolicy;
use deepfoids_sensors::{AZ_CELLS, EL_CELLS, STACKED_CHANNELS, STACKED_LEN};
use numpy::ndarray::{ArrayView1, ArrayView2, ArrayView4};
use numpy::{
    PyArray1, PyArray2, PyArray4, PyReadonlyArray2, PyReadonlyArray4, PyUntypedArrayMethods,
};
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rayon::prelude::*;
use std::path::PathBuf;

/// Columns of [`Core::state`]: position (m), unit heading, speed (m/s), body
/// length (m), behaviour index.
const STATE_COLUMNS: usize = 9;

/// One environment and the agent-major buffers Python reads (see the module doc).
#[pyclass(module = "deepfoids._core")]
struct Core {
    env: Env,
    n: usize,
    /// Whether `grid` is a view of the env's output (one behaviour) or `own_grid`.
    view_grid: bool,
    /// Address of the env's grid buffer when viewed, checked after each step.
    viewed_at: usize,
    own_grid: Vec<f32>,
    vector: Vec<f32>,
    reward: Vec<f32>,
    terms: Vec<f32>,
    terminated: Vec<bool>,
    truncated: Vec<bool>,
    decided: Vec<bool>,
    actions: Vec<Vec<f32>>,
}

fn value_error(e: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(e.to_string())
}

/// A seed for episode `episode` of a run seeded with `seed` (SplitMix64 over both):
/// reproducible, and far apart for neighbouring seeds and episodes.
/// Episode 0 is `seed` itself.
fn episode_seed(seed: u64, episode: u64) -> u64 {
    if episode == 0 {
        return seed;
    }
    let mut z = seed ^ episode.wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

impl Core {
    fn from_scene(scene: Scene, seed: u64) -> Self {
        let env = Env::new(scene, seed);
        let n = env.world().len();
        let view_grid = env.behaviours().len() == 1;
        let mut core = Self {
            n,
            view_grid,
            viewed_at: 0,
            own_grid: if view_grid {
                Vec::new()
            } else {
                vec![0.0; n * STACKED_LEN]
            },
            vector: vec![0.0; n * VECTOR_OBS],
            reward: vec![0.0; n],
            terms: vec![0.0; n * N_TERMS],
            terminated: vec![false; n],
            truncated: vec![false; n],
            decided: vec![false; n],
            actions: env
                .behaviours()
                .iter()
                .map(|b| vec![0.0; b.count * 3])
                .collect(),
            env,
        };
        core.viewed_at = core.env_grid_address();
        core.copy_output();
        core
    }

    fn env_grid_address(&self) -> usize {
        self.env.output().behaviours[0].grids.as_ptr() as usize
    }

    /// Copy the latest output into the agent-major buffers. Rows of behaviours
    /// that did not decide keep their observation; their reward is zero.
    fn copy_output(&mut self) {
        for batch in &self.env.output().behaviours {
            let rows = batch.first..batch.first + batch.n_agents;
            self.decided[rows.clone()].fill(batch.decided);
            if !batch.decided {
                self.reward[rows.clone()].fill(0.0);
                self.terms[rows.start * N_TERMS..rows.end * N_TERMS].fill(0.0);
                self.terminated[rows.clone()].fill(false);
                self.truncated[rows].fill(false);
                continue;
            }
            self.vector[rows.start * VECTOR_OBS..rows.end * VECTOR_OBS]
                .copy_from_slice(&batch.vectors);
            self.reward[rows.clone()].copy_from_slice(&batch.rewards);
            self.terms[rows.start * N_TERMS..rows.end * N_TERMS]
                .copy_from_slice(batch.terms.as_flattened());
            self.terminated[rows.clone()].copy_from_slice(&batch.terminated);
            self.truncated[rows.clone()].copy_from_slice(&batch.truncated);
            if !self.view_grid {
                self.own_grid[rows.start * STACKED_LEN..rows.end * STACKED_LEN]
                    .par_chunks_mut(STACKED_LEN)
                    .zip(batch.grids.par_chunks(STACKED_LEN))
                    .with_min_len(16)
                    .for_each(|(to, from)| to.copy_from_slice(from));
            }
        }
    }

    fn advance(&mut self) -> PyResult<()> {
        self.env.step(&self.actions).map_err(value_error)?;
        if self.view_grid && self.env_grid_address() != self.viewed_at {
            return Err(PyRuntimeError::new_err(
                "the environment moved its observation buffer during a step \
                 (Env::step must not reallocate); the grid view is no longer valid",
            ));
        }
        self.copy_output();
        Ok(())
    }

    fn grid_slice(&self) -> &[f32] {
        if self.view_grid {
            &self.env.output().behaviours[0].grids
        } else {
            &self.own_grid
        }
    }
}

#[pymethods]
impl Core {
    /// Load `scene` (an id of `configs/scenes/` or a path to a scene TOML) with the
    /// reward weights of `phase` in `reward_profile` (a folder of
    /// `configs/rewards/`; default: the CLI's default profile), and build its
    /// world from `seed`.
    #[new]
    #[pyo3(signature = (scene, phase, seed, configs, max_episode_decisions=None, reward_profile=None))]
    fn new(
        scene: &str,
        phase: &str,
        seed: u64,
        configs: PathBuf,
        max_episode_decisions: Option<i64>,
        reward_profile: Option<String>,
    ) -> PyResult<Self> {
        let phase: Phase = phase.parse().map_err(value_error)?;
        if !configs.join("scenes").is_dir() {
            return Err(value_error(format!(
                "configs folder {} has no scenes/ sub-folder (expected scenes/, species/, sites/, rewards/)",
                configs.display()
            )));
        }
        let mut dirs = ConfigDirs::new(configs);
        if let Some(profile) = reward_profile {
            dirs = dirs.with_reward_profile(&profile);
        }
        let mut scene = Scene::load(&dirs, scene, phase).map_err(value_error)?;
        if let Some(m) = max_episode_decisions {
            if !(1..=i64::from(u32::MAX)).contains(&m) {
                return Err(value_error(format!(
                    "max_episode_decisions = {m}; it must be a whole number of decisions ≥ 1"
                )));
            }
            scene.physics.max_episode_decisions = m as u32;
        }
        Ok(Self::from_scene(scene, seed))
    }

    /// The same scene with a new world drawn from `seed`.
    fn reseeded(&self, seed: u64) -> Self {
        Self::from_scene(self.env.scene().clone(), seed)
    }

    /// The seed of episode `episode` of a run seeded with `seed`.
    #[staticmethod]
    fn episode_seed(seed: u64, episode: u64) -> u64 {
        episode_seed(seed, episode)
    }

    /// Advance one tick with `actions` `float32 [N, 3]` (rows of behaviours that
    /// did not decide at the previous tick are ignored). The GIL is released while
    /// the world steps and the buffers are rewritten.
    fn step(&mut self, py: Python<'_>, actions: PyReadonlyArray2<'_, f32>) -> PyResult<()> {
        let shape = actions.shape();
        if shape != [self.n, 3] {
            return Err(value_error(format!(
                "actions must be float32 [{}, 3] (one row per agent), got shape {shape:?}",
                self.n
            )));
        }
        let a = actions.as_slice().map_err(|_| {
            value_error("actions must be a C-contiguous array (use numpy.ascontiguousarray)")
        })?;
        for (b, info) in self.env.behaviours().iter().enumerate() {
            if self.env.awaiting(b) {
                self.actions[b].copy_from_slice(&a[info.first * 3..(info.first + info.count) * 3]);
            }
        }
        py.detach(|| self.advance())
    }

    /// The buffers as numpy arrays viewing this core's memory, read-only:
    /// `grid`, `vector`, `reward`, `terms`, `terminated`, `truncated`, `decided`.
    fn arrays<'py>(slf: Bound<'py, Self>) -> PyResult<Bound<'py, PyDict>> {
        let py = slf.py();
        let this = slf.borrow();
        let n = this.n;
        let dict = PyDict::new(py);
        let owner = || slf.clone().into_any();
        let shape_error = |e: numpy::ndarray::ShapeError| PyRuntimeError::new_err(e.to_string());
        // SAFETY (every view below): the memory belongs to `slf` (or to its env) and
        // is never reallocated while `slf` lives — the buffers are allocated once in
        // `from_scene`, and the env's grid buffer is checked after every step. The
        // owner is set as each array's base, so it outlives the arrays.
        unsafe {
            let grid = ArrayView4::from_shape(
                (n, STACKED_CHANNELS, EL_CELLS, AZ_CELLS),
                this.grid_slice(),
            )
            .map_err(shape_error)?;
            dict.set_item("grid", PyArray4::borrow_from_array(&grid, owner()))?;
            let vector =
                ArrayView2::from_shape((n, VECTOR_OBS), &this.vector).map_err(shape_error)?;
            dict.set_item("vector", PyArray2::borrow_from_array(&vector, owner()))?;
            let terms = ArrayView2::from_shape((n, N_TERMS), &this.terms).map_err(shape_error)?;
            dict.set_item("terms", PyArray2::borrow_from_array(&terms, owner()))?;
            let reward = ArrayView1::from(&this.reward);
            dict.set_item("reward", PyArray1::borrow_from_array(&reward, owner()))?;
            for (name, v) in [
                ("terminated", &this.terminated),
                ("truncated", &this.truncated),
                ("decided", &this.decided),
            ] {
                let view = ArrayView1::from(v);
                dict.set_item(name, PyArray1::borrow_from_array(&view, owner()))?;
            }
        }
        for (_, array) in dict.iter() {
            array.getattr("flags")?.setattr("writeable", false)?;
        }
        Ok(dict)
    }

    /// Per fish: position (m), unit heading, speed (m/s), body length (m) and
    /// behaviour index, as `float32 [N, 9]` (a new array).
    fn state<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f32>> {
        let w = self.env.world();
        let mut s = Vec::with_capacity(self.n * STATE_COLUMNS);
        for i in 0..self.n {
            let (p, h) = (w.position[i], w.heading[i]);
            s.extend_from_slice(&[
                p.x,
                p.y,
                p.z,
                h.x,
                h.y,
                h.z,
                w.speed[i],
                w.bl[i],
                f32::from(w.behaviour[i]),
            ]);
        }
        let a = numpy::ndarray::Array2::from_shape_vec((self.n, STATE_COLUMNS), s)
            .expect("state has N × 9 values");
        PyArray2::from_owned_array(py, a)
    }

    /// The behaviours, in fish order: name, species, size_class, first, count,
    /// steps_per_decision, period_ticks.
    fn behaviours<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyDict>>> {
        self.env
            .behaviours()
            .iter()
            .map(|b| {
                let d = PyDict::new(py);
                d.set_item("name", &b.name)?;
                d.set_item("species", &b.species)?;
                d.set_item("size_class", &b.size_class)?;
                d.set_item("first", b.first)?;
                d.set_item("count", b.count)?;
                d.set_item("steps_per_decision", b.steps_per_decision)?;
                d.set_item("period_ticks", b.period_ticks)?;
                Ok(d)
            })
            .collect()
    }

    /// Number of agents (fish).
    #[getter]
    fn n_agents(&self) -> usize {
        self.n
    }

    #[getter]
    fn scene_id(&self) -> String {
        self.env.scene().id.clone()
    }

    #[getter]
    fn seed(&self) -> u64 {
        self.env.seed()
    }

    /// Ticks since the world was built.
    #[getter]
    fn tick(&self) -> u64 {
        self.env.output().tick
    }

    /// Simulated seconds per tick.
    #[getter]
    fn tick_seconds(&self) -> f64 {
        self.env.tick_seconds()
    }

    #[getter]
    fn max_episode_decisions(&self) -> u32 {
        self.env.scene().physics.max_episode_decisions
    }

    /// The horizontal outline `(x, z)` of the cage walls (m), closed.
    fn cage_outline(&self) -> Vec<(f32, f32)> {
        self.env.cage().outline()
    }

    /// Obstacles seen from above: `(x, z, radius)` (m).
    fn obstacle_discs(&self) -> Vec<(f32, f32, f32)> {
        self.env
            .scene()
            .obstacles()
            .iter()
            .map(|o| match *o {
                deepfoids_sensors::Obstacle::Sphere { center, radius } => {
                    (center.x, center.z, radius)
                }
                deepfoids_sensors::Obstacle::Cylinder { x, z, radius, .. } => (x, z, radius),
            })
            .collect()
    }
}

/// An exported policy (`.onnx` with ML-Agents' interface) run by tract.
#[pyclass(module = "deepfoids._core")]
struct OnnxModel {
    policy: OnnxPolicy,
}

#[pymethods]
impl OnnxModel {
    #[new]
    fn new(path: PathBuf) -> PyResult<Self> {
        let policy = OnnxPolicy::load(&path, false).map_err(|e| value_error(format!("{e:#}")))?;
        Ok(Self { policy })
    }

    /// Actions `float32 [n, 3]` for `grid [n, 18, 20, 34]` and `vector [n, 6]`:
    /// the mean action, or a sample when `stochastic`. The GIL is released while
    /// the network runs.
    #[pyo3(signature = (grid, vector, stochastic=false))]
    fn run<'py>(
        &mut self,
        py: Python<'py>,
        grid: PyReadonlyArray4<'py, f32>,
        vector: PyReadonlyArray2<'py, f32>,
        stochastic: bool,
    ) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let n = grid.shape()[0];
        if grid.shape()[1..] != [STACKED_CHANNELS, EL_CELLS, AZ_CELLS] {
            return Err(value_error(format!(
                "grid must be float32 [n, {STACKED_CHANNELS}, {EL_CELLS}, {AZ_CELLS}], got {:?}",
                grid.shape()
            )));
        }
        if vector.shape() != [n, VECTOR_OBS] {
            return Err(value_error(format!(
                "vector must be float32 [{n}, {VECTOR_OBS}] (as many rows as grid), got {:?}",
                vector.shape()
            )));
        }
        let contiguous = |_| value_error("observations must be C-contiguous arrays");
        let (g, v) = (
            grid.as_slice().map_err(contiguous)?,
            vector.as_slice().map_err(contiguous)?,
        );
        self.policy.stochastic = stochastic;
        let policy = &self.policy;
        let actions = py
            .detach(|| policy.run(g, v, n))
            .map_err(|e| PyRuntimeError::new_err(format!("{e:#}")))?;
        let a = numpy::ndarray::Array2::from_shape_vec((n, 3), actions)
            .map_err(|e| PyRuntimeError::new_err(e.to_string()))?;
        Ok(PyArray2::from_owned_array(py, a))
    }

    /// The file's metadata (species, behaviour, scene, algorithm, training step, …).
    #[getter]
    fn metadata(&self) -> std::collections::HashMap<String, String> {
        self.policy.metadata.clone()
    }

    #[getter]
    fn path(&self) -> PathBuf {
        self.policy.path.clone()
    }
}

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Core>()?;
    m.add_class::<OnnxModel>()?;
    m.add("TERM_NAMES", TERM_NAMES.to_vec())?;
    m.add("VECTOR_OBS", VECTOR_OBS)?;
    m.add("GRID_SHAPE", (STACKED_CHANNELS, EL_CELLS, AZ_CELLS))?;
    Ok(())
}
