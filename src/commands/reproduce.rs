//! `deepfoids reproduce`: the experiments of thesis §4.5, each claim judged,
//! and a report (see `deepfoids_experiments::reproduce`).

use anyhow::Result;
use clap::Args;
use clap::builder::{PossibleValuesParser, TypedValueParser};
use deepfoids_env::ConfigDirs;
use deepfoids_experiments::reproduce::{Mode, ProfileName, ReproduceOptions};
use std::path::PathBuf;

#[derive(Args, Debug, Clone)]
pub struct ReproduceArgs {
    /// Budgets: `full` (the thesis': coho 4 M + 1 M, yellowtail and seabream 2 M + 2 M, SAC on coho 4 M + 1 M) or `quick` (a tenth of them)
    #[arg(long, default_value = "full", value_parser = profile())]
    pub profile: ProfileName,
    /// Only these claims (comma-separated), and the stages they need [default: every claim]; see the README for the list
    #[arg(long, value_delimiter = ',', value_name = "CLAIM")]
    pub only: Vec<String>,
    /// Output folder: the runs (s<seed>/<stage>) and report/
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Training seeds [default: the profile's]
    #[arg(long, value_delimiter = ',')]
    pub seeds: Vec<u64>,
    /// Scale every training budget by this factor (tests; the report says so)
    #[arg(long, default_value_t = 1.0, hide = true)]
    pub budget_scale: f64,
    /// Scale the evaluation's simulated seconds by this factor (tests)
    #[arg(long, default_value_t = 1.0, hide = true)]
    pub eval_scale: f64,
    /// After the report, copy the shipped policies (each species' transferred default policy, coho's density-cage transfers) with model cards into this folder (`policies` ships them with the repository); their stages are trained first
    #[arg(long, value_name = "DIR")]
    pub ship: Option<PathBuf>,
    /// With --ship: ship only these (comma-separated: `coho`, `coho/density_dense`, …); the others in the folder stay
    #[arg(long, value_delimiter = ',', value_name = "NAME", requires = "ship")]
    pub ship_only: Vec<String>,
    /// No progress bars or progress lines while training
    #[arg(long)]
    pub quiet: bool,
    /// Evaluate with the policies' means instead of sampled actions (the default, as Unity's inference did)
    #[arg(long)]
    pub deterministic: bool,
    /// Print the stages to train as JSON lines (seed, stage, the stages it starts from) and stop: what `deepfoids.ray` schedules
    #[arg(long, conflicts_with_all = ["stage", "ship"])]
    pub plan: bool,
    /// Train only this stage (each seed) once the stages it starts from are finished, and stop; several may run at once
    #[arg(long, value_name = "NAME", conflicts_with = "ship")]
    pub stage: Option<String>,
}

/// `--profile`: full or quick, listed in `--help` and in the error.
fn profile() -> impl TypedValueParser<Value = ProfileName> {
    PossibleValuesParser::new(ProfileName::ALL.map(|(name, _)| name))
        .try_map(|s| s.parse::<ProfileName>())
}

pub fn run(dirs: &ConfigDirs, args: &ReproduceArgs) -> Result<()> {
    deepfoids_experiments::reproduce::run(
        dirs,
        &ReproduceOptions {
            profile: args.profile,
            only: args.only.clone(),
            out: args.out.clone(),
            seeds: args.seeds.clone(),
            budget_scale: args.budget_scale,
            eval_scale: args.eval_scale,
            ship: args.ship.clone(),
            ship_only: args.ship_only.clone(),
            quiet: args.quiet,
            deterministic: args.deterministic,
            mode: args
                .stage
                .clone()
                .map_or(if args.plan { Mode::Plan } else { Mode::All }, Mode::Stage),
        },
    )
}
