//! Splitting a data set into an identification part and a held-out validation part.
use super::data_file::DataSet;
use rand::seq::SliceRandom;
use rand::SeedableRng;

/// Which poses go to the first part (the rest go to the second).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SplitRule {
    /// Poses whose id is below this value.
    IdBelow(i64),
    /// Poses with an even id.
    EvenIds,
    /// A random fraction of the poses (rounded), drawn with a seed.
    Random {
        /// Fraction in the first part, in (0, 1).
        fraction: f64,
        /// Seed of the draw.
        seed: u64,
    },
}

impl SplitRule {
    /// Parse `below:ID`, `even` or `random:FRACTION` (the seed is given apart).
    pub fn parse(text: &str, seed: u64) -> Result<SplitRule, String> {
        let bad = || format!("'{text}': expected below:ID, even or random:FRACTION (e.g. below:500, random:0.5)");
        match text.split_once(':') {
            None if text == "even" => Ok(SplitRule::EvenIds),
            Some(("below", v)) => v.trim().parse().map(SplitRule::IdBelow).map_err(|_| bad()),
            Some(("random", v)) => match v.trim().parse::<f64>() {
                Ok(f) if f > 0.0 && f < 1.0 => Ok(SplitRule::Random { fraction: f, seed }),
                _ => Err(bad()),
            },
            _ => Err(bad()),
        }
    }
}

/// The subset of `data` at row indices `rows` (in that order), with its reflectors.
pub fn subset(data: &DataSet, rows: &[usize]) -> DataSet {
    DataSet {
        path: data.path.clone(),
        measurements: rows.iter().map(|&i| data.measurements[i].clone()).collect(),
        lines: rows.iter().map(|&i| data.lines[i]).collect(),
        ids: rows.iter().map(|&i| data.ids[i]).collect(),
        format: data.format,
        has_inputs: data.has_inputs,
        dropped: Vec::new(),
        reflectors: if data.reflectors.is_empty() {
            Vec::new()
        } else {
            rows.iter().map(|&i| data.reflectors[i]).collect()
        },
        derived: data.derived.clone(),
        // (Said when the whole file was read.)
        beyond_limits: Vec::new(),
    }
}

/// Which of the poses `ids` (in file order) go to the first part under `rule`.
fn selected(ids: &[i64], rule: SplitRule) -> Vec<bool> {
    let n = ids.len();
    match rule {
        SplitRule::IdBelow(v) => ids.iter().map(|&id| id < v).collect(),
        SplitRule::EvenIds => ids.iter().map(|&id| id.rem_euclid(2) == 0).collect(),
        SplitRule::Random { fraction, seed } => {
            let mut order: Vec<usize> = (0..n).collect();
            order.shuffle(&mut rand_chacha::ChaCha8Rng::seed_from_u64(seed));
            let k = (fraction * n as f64).round() as usize;
            let mut f = vec![false; n];
            for &i in &order[..k.min(n)] {
                f[i] = true;
            }
            f
        }
    }
}

/// The ids of `ids` (in file order) that `rule` puts in the first part: the same poses
/// [`split`] selects from a data set with those ids.
pub fn subset_ids(ids: &[i64], rule: SplitRule) -> Vec<i64> {
    ids.iter().zip(selected(ids, rule)).filter(|(_, f)| *f).map(|(id, _)| *id).collect()
}

/// Split `data` by `rule` into (first, rest), each keeping the file order.
pub fn split(data: &DataSet, rule: SplitRule) -> (DataSet, DataSet) {
    let n = data.ids.len();
    let first = selected(&data.ids, rule);
    let a: Vec<usize> = (0..n).filter(|&i| first[i]).collect();
    let b: Vec<usize> = (0..n).filter(|&i| !first[i]).collect();
    (subset(data, &a), subset(data, &b))
}
