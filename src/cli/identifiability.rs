//! `kinecal identifiability MODEL [DATA]`: rank, redundant parameters and conditioning of the
//! identification problem at the model, on measured poses or on random ones.
use super::simulate::MeasureKind;
use clap::Args;
use kinecal::identifiability::{analyze, DEFAULT_RANK_TOLERANCE};
use kinecal::identify::linearize;
use kinecal::io::data_file::{read_data, InputColumns};
use kinecal::io::model_file::ModelFile;
use kinecal::measure::{Measurement, Noise};
use kinecal::simulate::{random_configurations, synthesize, Instrument};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::path::PathBuf;

/// Arguments of `kinecal identifiability`.
#[derive(Args, Debug)]
pub struct IdentifiabilityArgs {
    /// Model file or built-in name; its [calibration] free list is the candidate set, in priority order.
    pub model: String,
    /// Data file whose poses (inputs and measurement kind) to analyse; without it, random poses.
    pub data: Option<PathBuf>,
    /// Number of random poses when no data file is given.
    #[arg(long, default_value_t = 100)]
    pub poses: usize,
    /// Seed of the random poses.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Measurement kind of the random poses (reflectors = pose).
    #[arg(long, value_enum, default_value_t = MeasureKind::Pose)]
    pub measure: MeasureKind,
    /// Relative singular-value tolerance of the rank decision.
    #[arg(long, default_value_t = DEFAULT_RANK_TOLERANCE)]
    pub tolerance: f64,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// Seat data: a known distance between two seats, `A:B:MM` (their scale); repeat for more.
    #[arg(long = "seat-distance", value_name = "A:B:MM")]
    pub seat_distances: Vec<kinecal::instrument::SeatDistance>,
}

/// Run the command.
pub fn run(a: IdentifiabilityArgs) -> anyhow::Result<()> {
    let file = ModelFile::load_or_builtin(&a.model)?;
    let mut model = file.build();
    let inputs = file.inputs();
    let mut free = file.free_indices()?;
    let mut instrument = false;
    let data: Vec<Measurement> = match &a.data {
        Some(p) => {
            let mut set = read_data(p, &file.data_columns(), InputColumns::Required)?;
            super::warn_limits(&set);
            if let Some(u) = set.set_aside_unassembled(&*model)? {
                eprintln!("warning: {}", u.note(&set));
            }
            // Instrument data: the model the fit uses (tool-point offset, seats and pivots).
            match kinecal::calibrate::instrument_model(&file, &set, &a.seat_distances)? {
                Some((start, f, measurements)) => {
                    (model, free, instrument) = (start, f, true);
                    measurements
                }
                None => set.measurements,
            }
        }
        None => {
            let mut rng = ChaCha8Rng::seed_from_u64(a.seed);
            let configurations = random_configurations(&*model, &inputs, a.poses, &mut rng)?;
            let exact = Noise {
                position: 0.0,
                orientation: 0.0,
                joint_angle: 0.0,
                joint_length: 0.0,
                kinds: Default::default(),
            };
            let instrument = match a.measure {
                MeasureKind::Position => Instrument::Position,
                _ => Instrument::Pose,
            };
            synthesize(&*model, configurations, instrument, &exact, &mut rng, &|_| {})?.measurements
        }
    };
    let noise = file.noise.unwrap_or_default();
    let lin = linearize(&*model, &data, &noise)?;
    let id = analyze(&lin.jacobian, &free, a.tolerance);
    let params = model.params();
    let names = |v: &[usize]| v.iter().map(|&i| params[i].name.clone()).collect::<Vec<_>>();
    if a.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::json!({
                "model": file.name, "poses": data.len(), "free": free.len(), "rank": id.rank,
                "identifiable": names(&id.identifiable), "redundant": names(&id.redundant),
                "no_effect": names(&id.no_effect), "pivoted": names(&id.pivoted),
                "held_by_assembly": file.held_by_assembly(),
                "condition": id.condition, "singular_values": id.singular_values,
            }))?
        );
    } else {
        println!(
            "{}: {}, {} free parameters, rank {}, condition number {:.3e}",
            file.name,
            super::count(data.len(), "pose"),
            free.len(),
            id.rank,
            id.condition
        );
        println!("redundant ({}): {}", id.redundant.len(), names(&id.redundant).join(" "));
        if !id.no_effect.is_empty() {
            println!("no effect ({}): {}", id.no_effect.len(), names(&id.no_effect).join(" "));
        }
        println!("identifiable ({}): {}", id.identifiable.len(), names(&id.identifiable).join(" "));
        let held = file.held_by_assembly();
        if !held.is_empty() {
            println!(
                "held as drawn ({}, not free: {} is overconstrained and would not assemble with any one of them changed): {}",
                held.len(),
                file.name,
                held.join(" ")
            );
        }
        if instrument {
            println!(
                "instrument data: the machine's base is not placed (the seats and pivots are somewhere unknown: moving the base and them together changes nothing measured), so that rigid motion is redundant and shows above on the last of those parameters in priority order; the tool point's offset (tx ty tz) and every seat and pivot (seatN.x …) are estimated"
            );
        }
    }
    Ok(())
}
