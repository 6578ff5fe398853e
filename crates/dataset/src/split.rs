//! `dataset split`: episodes dealt into named splits by a seeded shuffle within each task
//! (stratified: every task's episodes split in the same fractions), each split written
//! as a dataset of its own under one output folder, with `split.json` recording which
//! source episodes went where.

use std::collections::BTreeMap;
use std::path::Path;

use dexjoco_core::Progress;
use dexjoco_formats::dataset::lerobot_read::LeRobotDataset;
use dexjoco_formats::fs::StagedDir;
use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use crate::subset::check_output;
use crate::{EditError, SubsetReport, write_subset};

/// The record of which source episodes went where, beside the splits.
const SPLIT_RECORD: &str = "split.json";

/// How large each split is.
#[derive(Debug, Clone, PartialEq)]
pub struct SplitSizes(pub Vec<(String, f64)>);

impl std::str::FromStr for SplitSizes {
    type Err = String;

    /// `train=0.8,val=0.2` (fractions summing to at most 1).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let mut parts = Vec::new();
        for part in s.split(',').map(str::trim).filter(|p| !p.is_empty()) {
            let (name, f) = part
                .split_once('=')
                .ok_or_else(|| format!("{part:?}: expected NAME=FRACTION, as train=0.8"))?;
            let f: f64 = f
                .trim()
                .parse()
                .map_err(|_| format!("{part:?}: {f:?} is no fraction"))?;
            let name = name.trim();
            if !(0.0..=1.0).contains(&f) {
                return Err(format!(
                    "{part:?}: a split is NAME=FRACTION with 0 <= FRACTION <= 1"
                ));
            }
            // Each split is a folder of the output, beside split.json.
            dexjoco_core::safe_name("split name", name).map_err(|e| e.to_string())?;
            if name == SPLIT_RECORD {
                return Err(format!(
                    "{part:?}: {SPLIT_RECORD} is the split record's name"
                ));
            }
            if parts.iter().any(|(n, _): &(String, f64)| n == name) {
                return Err(format!("split {name:?} is named twice"));
            }
            parts.push((name.to_owned(), f));
        }
        let sum: f64 = parts.iter().map(|(_, f)| f).sum();
        if parts.is_empty() || sum > 1.0 + 1e-9 {
            return Err(format!(
                "{s:?}: one or more NAME=FRACTION summing to at most 1"
            ));
        }
        Ok(Self(parts))
    }
}

/// Which source episodes each split gets (ascending source indices).
#[derive(Debug, Clone, Serialize, PartialEq, Eq)]
pub struct SplitPlan {
    /// The seed of the shuffle.
    pub seed: u64,
    /// Split name and its source episode indices, in the order the splits were named.
    pub splits: Vec<(String, Vec<usize>)>,
}

/// Deals the episodes of `ds` into `sizes`: per task (an episode's first task), a
/// shuffle seeded by `seed`; each split gets its share of the whole dataset exactly
/// (largest remainder), spread over the tasks in proportion ([`allocate`]).
pub fn plan_split(
    ds: &LeRobotDataset,
    sizes: &SplitSizes,
    seed: u64,
) -> Result<SplitPlan, EditError> {
    let tasks = ds.episode_tasks()?;
    let mut by_task: BTreeMap<String, Vec<usize>> = BTreeMap::new();
    for (i, t) in tasks.iter().enumerate() {
        by_task
            .entry(t.first().cloned().unwrap_or_default())
            .or_default()
            .push(i);
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut groups: Vec<Vec<usize>> = by_task.into_values().collect();
    for g in &mut groups {
        g.shuffle(&mut rng);
    }
    let sizes_of: Vec<usize> = groups.iter().map(Vec::len).collect();
    let counts = allocate(&sizes_of, &sizes.0);
    let mut splits: Vec<(String, Vec<usize>)> = sizes
        .0
        .iter()
        .map(|(n, _)| (n.clone(), Vec::new()))
        .collect();
    for (g, row) in groups.iter().zip(&counts) {
        let mut at = 0;
        for ((_, rows), n) in splits.iter_mut().zip(row) {
            rows.extend_from_slice(&g[at..at + n]);
            at += n;
        }
    }
    for (name, rows) in &mut splits {
        rows.sort_unstable();
        if rows.is_empty() {
            return Err(EditError::Selection(format!(
                "split {name:?} gets no episode of the {} in '{}': give it a larger fraction",
                ds.len(),
                ds.root.display()
            )));
        }
    }
    Ok(SplitPlan { seed, splits })
}

/// How many episodes of each group (task) each split gets: every split's total is its
/// share of all episodes by largest remainder ([`shares`]); within that, each group
/// gets the floor of its proportional quota, and the episodes left go to the largest
/// fractional quotas among groups with episodes to spare.
fn allocate(groups: &[usize], fractions: &[(String, f64)]) -> Vec<Vec<usize>> {
    let total: usize = groups.iter().sum();
    let targets = shares(total, fractions);
    let quota = |g: usize, s: usize| groups[g] as f64 * fractions[s].1;
    let mut counts: Vec<Vec<usize>> = (0..groups.len())
        .map(|g| {
            (0..fractions.len())
                .map(|s| quota(g, s).floor() as usize)
                .collect()
        })
        .collect();
    let mut cells: Vec<(usize, usize)> = (0..groups.len())
        .flat_map(|g| (0..fractions.len()).map(move |s| (g, s)))
        .collect();
    let frac = |&(g, s): &(usize, usize)| quota(g, s) - quota(g, s).floor();
    cells.sort_by(|a, b| frac(b).total_cmp(&frac(a)).then(a.cmp(b)));
    // Largest remainders first, then any group with room, until every split has its total.
    for pass in 0..2 {
        for &(g, s) in &cells {
            let given: usize = counts.iter().map(|row| row[s]).sum();
            let room = groups[g] - counts[g].iter().sum::<usize>();
            if given < targets[s] && room > 0 && (pass == 1 || frac(&(g, s)) > 0.0) {
                counts[g][s] += 1;
            }
        }
    }
    counts
}

/// Split sizes of `n` episodes by fractions: floors, then the episodes the fractions
/// still ask for to the largest remainders (ties to the split named first).
fn shares(n: usize, fractions: &[(String, f64)]) -> Vec<usize> {
    let quotas: Vec<f64> = fractions.iter().map(|(_, f)| f * n as f64).collect();
    let mut counts: Vec<usize> = quotas.iter().map(|q| q.floor() as usize).collect();
    let wanted = (quotas.iter().sum::<f64>() + 1e-9).floor() as usize;
    let mut order: Vec<usize> = (0..fractions.len()).collect();
    order.sort_by(|a, b| {
        let (ra, rb) = (
            quotas[*a] - quotas[*a].floor(),
            quotas[*b] - quotas[*b].floor(),
        );
        rb.total_cmp(&ra).then(a.cmp(b))
    });
    let mut left = wanted.min(n).saturating_sub(counts.iter().sum());
    for i in order {
        if left == 0 {
            break;
        }
        counts[i] += 1;
        left -= 1;
    }
    counts
}

/// Splits the dataset at `source` into datasets `out/<split>` (the whole folder staged
/// and renamed at once), and `out/split.json`.
pub fn split(
    source: &Path,
    sizes: &SplitSizes,
    seed: u64,
    out: &Path,
    overwrite: bool,
    progress: &dyn Progress,
) -> Result<Vec<(String, SubsetReport)>, EditError> {
    let ds = LeRobotDataset::open(source)?;
    let plan = plan_split(&ds, sizes, seed)?;
    check_output(source, out, overwrite)?;
    let staged = StagedDir::begin(out)?;
    let mut reports = Vec::new();
    for (name, rows) in &plan.splits {
        let dir = staged.path().join(name);
        fs_err::create_dir_all(&dir)?;
        let splits = BTreeMap::from([(name.clone(), format!("0:{}", rows.len()))]);
        reports.push((
            name.clone(),
            write_subset(&ds, rows, None, &dir, Some(splits), progress)?,
        ));
    }
    let record = serde_json::json!({
        "source": source.display().to_string(),
        "seed": plan.seed,
        "stratified_by": "task",
        "splits": plan.splits.iter().map(|(n, r)| (n.clone(), r.clone())).collect::<BTreeMap<_, _>>(),
    });
    fs_err::write(
        staged.path().join(SPLIT_RECORD),
        serde_json::to_string_pretty(&record).expect("json") + "\n",
    )?;
    staged.commit()?;
    Ok(reports)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shares_add_up_by_largest_remainder() {
        let f = |v: &[f64]| v.iter().map(|x| (String::new(), *x)).collect::<Vec<_>>();
        assert_eq!(shares(10, &f(&[0.8, 0.2])), vec![8, 2]);
        assert_eq!(shares(7, &f(&[0.5, 0.5])), vec![4, 3]);
        assert_eq!(shares(3, &f(&[0.6, 0.2, 0.2])), vec![2, 1, 0]);
        assert_eq!(shares(10, &f(&[0.5])), vec![5]);
        let s: SplitSizes = "train=0.8, val=0.2".parse().unwrap();
        assert_eq!(s.0.len(), 2);
        assert!("train=0.8,val=0.3".parse::<SplitSizes>().is_err());
        assert!("train".parse::<SplitSizes>().is_err());
        for bad in [
            "..=0.5",
            ".=0.5",
            "a/b=0.5",
            ".hidden=0.5",
            "split.json=0.5",
        ] {
            assert!(bad.parse::<SplitSizes>().is_err(), "{bad}");
        }
    }

    #[test]
    fn small_tasks_still_fill_every_split() {
        let f = |v: &[f64]| v.iter().map(|x| (String::new(), *x)).collect::<Vec<_>>();
        // 11 tasks of 4 episodes, 0.9 / 0.1: 40 and 4 overall, each task 3 or 4 in train.
        let counts = allocate(&[4; 11], &f(&[0.9, 0.1]));
        let totals: Vec<usize> = (0..2).map(|s| counts.iter().map(|r| r[s]).sum()).collect();
        assert_eq!(totals, vec![40, 4]);
        assert!(counts.iter().all(|r| r[0] + r[1] == 4 && r[0] >= 3));
        // 3 + 5 episodes, 0.75 / 0.25: 6 and 2, one of each task in val.
        assert_eq!(
            allocate(&[3, 5], &f(&[0.75, 0.25])),
            vec![vec![2, 1], vec![4, 1]]
        );
    }
}
