//! Which episodes a filter keeps: index lists, tasks, a length range and predicates on
//! any per-episode column (`success == true`, `rand/light < 0.5`, `source == "ep3"`).

use std::str::FromStr;

use arrow_array::{Array, ArrayRef, BooleanArray};
use arrow_schema::DataType;
use dexjoco_formats::dataset::lerobot_read::{LeRobotDataset, strings};

use crate::EditError;

/// A comparison of a predicate.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Comparison {
    /// `==`
    Eq,
    /// `!=`
    Ne,
    /// `<`
    Lt,
    /// `<=`
    Le,
    /// `>`
    Gt,
    /// `>=`
    Ge,
}

/// `COLUMN OP VALUE` on a per-episode column: numbers and booleans compare as numbers
/// (true = 1), text as text (`==` / `!=` only); a value may be quoted.
#[derive(Debug, Clone, PartialEq)]
pub struct Predicate {
    /// The column of `meta/episodes` (`length`, `success`, `rand/light_intensity`).
    pub column: String,
    /// The comparison.
    pub op: Comparison,
    /// The value, as written.
    pub value: String,
}

impl FromStr for Predicate {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        // Two-character operators first, so `<=` is not read as `<`.
        const OPS: [(&str, Comparison); 6] = [
            ("==", Comparison::Eq),
            ("!=", Comparison::Ne),
            ("<=", Comparison::Le),
            (">=", Comparison::Ge),
            ("<", Comparison::Lt),
            (">", Comparison::Gt),
        ];
        let (at, text, op) = OPS
            .iter()
            .filter_map(|(text, op)| s.find(text).map(|at| (at, *text, *op)))
            .min_by_key(|(at, text, _)| (*at, std::cmp::Reverse(text.len())))
            .ok_or_else(|| {
                format!("{s:?}: expected COLUMN OP VALUE with OP one of == != < <= > >=")
            })?;
        let column = s[..at].trim().to_owned();
        let value = s[at + text.len()..].trim();
        let value = value
            .strip_prefix('"')
            .and_then(|v| v.strip_suffix('"'))
            .or_else(|| value.strip_prefix('\'').and_then(|v| v.strip_suffix('\'')))
            .unwrap_or(value)
            .to_owned();
        if column.is_empty() {
            return Err(format!("{s:?}: no column before the operator"));
        }
        Ok(Self { column, op, value })
    }
}

impl Predicate {
    /// Whether each episode satisfies the predicate; a null value never does.
    fn evaluate(&self, ds: &LeRobotDataset) -> Result<Vec<bool>, EditError> {
        let col = ds.column(&self.column).ok_or_else(|| {
            EditError::Selection(format!(
                "no per-episode column {:?} in '{}' (it has: {})",
                self.column,
                ds.root.display(),
                column_names(ds).join(", ")
            ))
        })?;
        match col.data_type() {
            DataType::Utf8 | DataType::LargeUtf8 | DataType::Utf8View => self.on_text(col),
            _ => self.on_numbers(col),
        }
    }

    fn on_text(&self, col: &ArrayRef) -> Result<Vec<bool>, EditError> {
        let want = match self.op {
            Comparison::Eq => true,
            Comparison::Ne => false,
            _ => {
                return Err(EditError::Selection(format!(
                    "column {:?} holds text: only == and != compare it",
                    self.column
                )));
            }
        };
        Ok(strings(col)
            .iter()
            .enumerate()
            .map(|(i, s)| !col.is_null(i) && (*s == self.value) == want)
            .collect())
    }

    fn on_numbers(&self, col: &ArrayRef) -> Result<Vec<bool>, EditError> {
        let value = match self.value.to_ascii_lowercase().as_str() {
            "true" => 1.0,
            "false" => 0.0,
            v => v.parse::<f64>().map_err(|_| {
                EditError::Selection(format!(
                    "column {:?} holds {}: {:?} is no number (or true/false)",
                    self.column,
                    col.data_type(),
                    self.value
                ))
            })?,
        };
        let numbers = numbers(col).ok_or_else(|| {
            EditError::Selection(format!(
                "column {:?} holds {}, which a predicate cannot compare (numbers, booleans \
                 and text can be)",
                self.column,
                col.data_type()
            ))
        })?;
        Ok(numbers
            .iter()
            .map(|x| {
                x.is_some_and(|x| match self.op {
                    Comparison::Eq => x == value,
                    Comparison::Ne => x != value,
                    Comparison::Lt => x < value,
                    Comparison::Le => x <= value,
                    Comparison::Gt => x > value,
                    Comparison::Ge => x >= value,
                })
            })
            .collect())
    }
}

/// A numeric or boolean column as numbers (`None` for nulls); `None` for other types.
fn numbers(col: &ArrayRef) -> Option<Vec<Option<f64>>> {
    let as_f64 = if let Some(b) = col.as_any().downcast_ref::<BooleanArray>() {
        return Some(
            (0..b.len())
                .map(|i| (!b.is_null(i)).then(|| f64::from(u8::from(b.value(i)))))
                .collect(),
        );
    } else {
        arrow_cast::cast(col, &DataType::Float64).ok()?
    };
    let f = as_f64
        .as_any()
        .downcast_ref::<arrow_array::Float64Array>()?;
    Some(
        (0..f.len())
            .map(|i| (!f.is_null(i)).then(|| f.value(i)))
            .collect(),
    )
}

/// The per-episode columns of `ds`, for error messages.
pub(crate) fn column_names(ds: &LeRobotDataset) -> Vec<String> {
    ds.episodes
        .schema()
        .fields()
        .iter()
        .map(|f| f.name().clone())
        .filter(|n| !n.starts_with("stats/"))
        .collect()
}

/// Which episodes to keep: every condition given must hold (`keep`), or episodes
/// matching them all are the ones dropped (`drop`).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Selection {
    /// Episode index ranges (of the source, both ends included, as `--episodes 0,2,5-7`
    /// gives them: never expanded before they are checked against the dataset); empty:
    /// any.
    pub episodes: Vec<std::ops::RangeInclusive<usize>>,
    /// Task strings; empty: any.
    pub tasks: Vec<String>,
    /// Fewest frames.
    pub min_length: Option<usize>,
    /// Most frames.
    pub max_length: Option<usize>,
    /// Column predicates, all of which must hold.
    pub predicates: Vec<Predicate>,
    /// Drop the episodes matching instead of keeping them.
    pub drop: bool,
}

impl Selection {
    /// The source indices of the kept episodes, ascending.
    pub fn apply(&self, ds: &LeRobotDataset) -> Result<Vec<usize>, EditError> {
        let n = ds.len();
        if let Some(bad) = self.episodes.iter().find(|r| *r.end() >= n) {
            return Err(EditError::Selection(format!(
                "episode {} is out of range: '{}' has episodes 0..{}",
                bad.end(),
                ds.root.display(),
                n.saturating_sub(1)
            )));
        }
        let mut matches = vec![true; n];
        if !self.episodes.is_empty() {
            // Each range lies within the dataset now: marking it is bounded by its size.
            let mut listed = vec![false; n];
            for r in &self.episodes {
                listed[r.clone()].fill(true);
            }
            and(&mut matches, listed);
        }
        if !self.tasks.is_empty() {
            self.check_tasks(ds)?;
            let tasks = ds.episode_tasks()?;
            and(
                &mut matches,
                tasks
                    .iter()
                    .map(|t| t.iter().any(|t| self.tasks.contains(t))),
            );
        }
        if self.min_length.is_some() || self.max_length.is_some() {
            let lengths = ds.lengths()?;
            let (lo, hi) = (
                self.min_length.unwrap_or(0),
                self.max_length.unwrap_or(usize::MAX),
            );
            and(
                &mut matches,
                lengths.iter().map(|l| (lo..=hi).contains(&(*l as usize))),
            );
        }
        for p in &self.predicates {
            and(&mut matches, p.evaluate(ds)?);
        }
        Ok((0..n).filter(|i| matches[*i] != self.drop).collect())
    }

    fn check_tasks(&self, ds: &LeRobotDataset) -> Result<(), EditError> {
        let known = ds.task_names()?;
        if let Some(t) = self.tasks.iter().find(|t| !known.contains(t)) {
            return Err(EditError::Selection(format!(
                "no task {t:?} in '{}' (its tasks: {})",
                ds.root.display(),
                known
                    .iter()
                    .map(|k| format!("{k:?}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            )));
        }
        Ok(())
    }
}

fn and(matches: &mut [bool], more: impl IntoIterator<Item = bool>) {
    for (m, x) in matches.iter_mut().zip(more) {
        *m &= x;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn predicates_parse_operators_and_quotes() {
        let p: Predicate = "success == true".parse().unwrap();
        assert_eq!(
            (p.column.as_str(), p.op, p.value.as_str()),
            ("success", Comparison::Eq, "true")
        );
        let p: Predicate = "rand/light<=0.5".parse().unwrap();
        assert_eq!(
            (p.column.as_str(), p.op, p.value.as_str()),
            ("rand/light", Comparison::Le, "0.5")
        );
        let p: Predicate = "source != 'a b'".parse().unwrap();
        assert_eq!((p.op, p.value.as_str()), (Comparison::Ne, "a b"));
        assert!("length 3".parse::<Predicate>().is_err());
        assert!("== 3".parse::<Predicate>().is_err());
    }
}
