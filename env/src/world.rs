//! The state of the school, structure-of-arrays: one `Vec` per quantity,
//! indexed by fish. Fish are ordered by behaviour, so each behaviour's fish
//! form one contiguous range.

use glam::Vec3;

/// A fish's role in the dominance game (SPEC §6).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub enum Chase {
    #[default]
    None,
    /// A dominant fish chasing `target` since simulated time `since` (s).
    Aggressor { target: u32, since: f64 },
    /// A subordinate escaping from `aggressor`.
    Target { aggressor: u32 },
}

impl Chase {
    /// The other fish of the chase, if any.
    pub fn partner(&self) -> Option<usize> {
        match *self {
            Chase::None => None,
            Chase::Aggressor { target, .. } => Some(target as usize),
            Chase::Target { aggressor } => Some(aggressor as usize),
        }
    }
}

/// The school.
#[derive(Clone, Debug, Default)]
pub struct World {
    // Fixed per fish.
    /// Behaviour index of each fish.
    pub behaviour: Vec<u16>,
    /// Species index (into the scene's species list) of each fish.
    pub species: Vec<u16>,
    /// Body length (m): the species' body length times the fish's body scale.
    pub bl: Vec<f32>,
    /// Dominant fish may start chases.
    pub dominant: Vec<bool>,
    /// Preferred light band `[I_lpref, I_hpref]` (PAR).
    pub light_pref: Vec<[f32; 2]>,
    // State.
    /// Body centre (m).
    pub position: Vec<Vec3>,
    /// Unit heading; the fish faces its velocity.
    pub heading: Vec<Vec3>,
    /// Roll about the heading (rad), within ±θzt.
    pub roll: Vec<f32>,
    /// Speed (m/s).
    pub speed: Vec<f32>,
    /// Chase role.
    pub chase: Vec<Chase>,
    /// Simulated time since reset (s).
    pub time: f64,
}

impl World {
    pub fn len(&self) -> usize {
        self.position.len()
    }

    pub fn is_empty(&self) -> bool {
        self.position.is_empty()
    }

    /// Velocity of fish `i` (m/s).
    pub fn velocity(&self, i: usize) -> Vec3 {
        self.heading[i] * self.speed[i]
    }
}
