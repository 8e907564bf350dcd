//! The chase stage (SPEC §6, dominance): at each decision, after the rewards,
//! chases of the deciding fish end and new ones start.
//!
//! * A chase ends when the aggressor touched its target, when either of them
//!   crossed a boundary, when the target got behind the aggressor (outside its
//!   front half-space), or after `chase_timeout` seconds.
//! * A free dominant fish that did not cross starts a chase with probability
//!   `p_a` (stream `(seed, Chase, fish, tick)`) against its nearest free
//!   subordinate of its species within `d_sense`, found by the sensing pass.
//!
//! Both partners of every chase that started or ended are listed in `changed`
//! (their newest observation is recomputed: they see and know it at once).

use crate::config::PhysicsConfig;
use crate::reward::Outcome;
use crate::rng::{Purpose, Stream};
use crate::state::Since;
use crate::traits::BehaviourInfo;
use crate::world::{Chase, World};

/// End and start the chases of the behaviours with `deciding[b]`.
#[allow(clippy::too_many_arguments)]
pub(crate) fn update(
    world: &mut World,
    since: &[Since],
    outcome: &[Outcome],
    info: &[BehaviourInfo],
    deciding: &[bool],
    config: &PhysicsConfig,
    seed: u64,
    tick: u64,
    changed: &mut Vec<u32>,
) {
    changed.clear();
    let w = world;
    let now = w.time;
    let deciders = || {
        info.iter()
            .enumerate()
            .filter(|(b, _)| deciding[*b])
            .flat_map(|(_, i)| i.range())
    };
    for i in deciders() {
        if let Chase::Aggressor {
            target,
            since: start,
        } = w.chase[i]
        {
            let t = target as usize;
            let behind = (w.position[t] - w.position[i]).dot(w.heading[i]) < 0.0;
            let over = since[i].caught
                || since[i].crossed
                || since[t].crossed
                || behind
                // Half a step of slack: the clock sums f32 steps.
                || now - start >= (config.chase_timeout - 0.5 * config.dt_sim) as f64;
            if over {
                w.chase[i] = Chase::None;
                w.chase[t] = Chase::None;
                changed.push(i as u32);
                changed.push(target);
            }
        }
    }
    for i in deciders() {
        if !w.dominant[i] || w.chase[i] != Chase::None || since[i].crossed {
            continue;
        }
        let u = Stream::new(seed, Purpose::Chase, i as u64, tick).uniform();
        if u >= config.chase_probability {
            continue;
        }
        if let Some(t) = outcome[i].nearest_subordinate
            && w.chase[t as usize] == Chase::None
            && !since[t as usize].crossed
        {
            w.chase[i] = Chase::Aggressor {
                target: t,
                since: now,
            };
            w.chase[t as usize] = Chase::Target {
                aggressor: i as u32,
            };
            changed.push(i as u32);
            changed.push(t);
        }
    }
    changed.sort_unstable();
    changed.dedup();
}
