//! Visible task feedback (the monitor turns blue, the iPad's digits light up...), as
//! data in the scene: each MuJoCo custom text named `feedback...` holds one rule,
//!
//! ```text
//! <custom><text name="feedback_blue" data="when=display_blue; geom=display_screen; rgba=0.1 0.35 0.95 1"/></custom>
//! ```
//!
//! `when=NODE` (a checker node is true) or `when=NODE.OUTPUT>=X` (a node output is at
//! least X); `geom=NAME` or `body=NAME` (every geom of the body); `rgba=R G B A`. Rules
//! apply at render time to the abstract scene (after `update_scene`, before `draw`), so
//! the shared `MjModel` is never edited. Rules whose node the spec lacks are errors.

use dexjoco_core::{NameKind, TaskSpec};
use mujoco_rs::prelude::{MjModel, MjtObjBase, MjvScene};

use crate::checker::{SuccessChecker, name_id};
use crate::error::SimError;

#[derive(Debug, Clone, PartialEq)]
enum When {
    Node(String),
    AtLeast(String, String, f64),
}

#[derive(Debug, Clone, PartialEq)]
struct Rule {
    when: When,
    geoms: Vec<usize>,
    rgba: [f32; 4],
}

/// The feedback rules of a scene, resolved against a task.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Feedback {
    rules: Vec<Rule>,
}

impl Feedback {
    /// Reads the scene's `feedback*` custom texts; every name must resolve.
    pub fn new(spec: &TaskSpec, model: &MjModel) -> Result<Self, SimError> {
        let mut rules = Vec::new();
        let ntext = model.ffi().ntext as usize;
        for i in 0..ntext {
            let name = model.id_to_name(MjtObjBase::mjOBJ_TEXT, i).unwrap_or("");
            if !name.starts_with("feedback") {
                continue;
            }
            let adr = model.text_adr()[i] as usize;
            let len = (model.text_size()[i] as usize).saturating_sub(1);
            let bytes: Vec<u8> = model.text_data()[adr..adr + len]
                .iter()
                .map(|c| *c as u8)
                .collect();
            let text = String::from_utf8_lossy(&bytes).into_owned();
            rules.push(parse(spec, model, name, &text)?);
        }
        Ok(Self { rules })
    }

    /// Number of rules.
    pub fn len(&self) -> usize {
        self.rules.len()
    }

    /// No rules.
    pub fn is_empty(&self) -> bool {
        self.rules.is_empty()
    }

    /// The rules whose condition holds now, as (geom ids, rgba).
    pub fn active(&self, checker: &SuccessChecker) -> Vec<(&[usize], [f32; 4])> {
        self.rules
            .iter()
            .filter(|r| match &r.when {
                When::Node(n) => checker.value(n) == Some(true),
                When::AtLeast(n, o, x) => checker.output(n, o).is_some_and(|v| v >= *x),
            })
            .map(|r| (r.geoms.as_slice(), r.rgba))
            .collect()
    }

    /// Recolours the scene's geoms of every active rule (call after `update_scene`).
    pub fn apply(&self, checker: &SuccessChecker, scene: &mut MjvScene) {
        let active = self.active(checker);
        if active.is_empty() {
            return;
        }
        // SAFETY: `geoms` points to `maxgeom` geoms of which the first `ngeom` are
        // initialized by mjv_updateScene; we only write their rgba.
        unsafe {
            let s = scene.ffi_mut();
            let geoms = std::slice::from_raw_parts_mut(s.geoms, s.ngeom as usize);
            for g in geoms {
                if g.objtype != MjtObjBase::mjOBJ_GEOM as i32 {
                    continue;
                }
                for (ids, rgba) in &active {
                    if ids.contains(&(g.objid as usize)) {
                        g.rgba = *rgba;
                    }
                }
            }
        }
    }
}

fn parse(spec: &TaskSpec, model: &MjModel, name: &str, text: &str) -> Result<Rule, SimError> {
    let bad = |problem: String| SimError::FeedbackRule {
        name: name.into(),
        text: text.into(),
        problem,
    };
    let (mut when, mut geoms, mut rgba) = (None, Vec::new(), None);
    for part in text.split(';').map(str::trim).filter(|p| !p.is_empty()) {
        let (k, v) = part
            .split_once('=')
            .ok_or_else(|| bad(format!("'{part}' is not key=value")))?;
        let v = v.trim();
        match k.trim() {
            "when" => {
                let w = if let Some((lhs, x)) = v.split_once(">=") {
                    let (n, o) = lhs
                        .trim()
                        .split_once('.')
                        .ok_or_else(|| bad("a threshold needs NODE.OUTPUT".into()))?;
                    let x: f64 = x
                        .trim()
                        .parse()
                        .map_err(|_| bad(format!("bad number '{x}'")))?;
                    When::AtLeast(n.into(), o.into(), x)
                } else {
                    When::Node(v.into())
                };
                let node = match &w {
                    When::Node(n) | When::AtLeast(n, _, _) => n,
                };
                if !spec.nodes.contains_key(node.as_str()) {
                    return Err(bad(format!("task '{}' has no node '{node}'", spec.id)));
                }
                when = Some(w);
            }
            "geom" => geoms.push(
                name_id(model, NameKind::Geom, v).ok_or_else(|| bad(format!("no geom '{v}'")))?,
            ),
            "body" => {
                let b = name_id(model, NameKind::Body, v)
                    .ok_or_else(|| bad(format!("no body '{v}'")))?;
                geoms.extend(
                    (0..model.ffi().ngeom as usize)
                        .filter(|&g| model.geom_bodyid()[g] as usize == b),
                );
            }
            "rgba" => {
                let vals: Vec<f32> = v
                    .split_whitespace()
                    .map(str::parse)
                    .collect::<Result<_, _>>()
                    .map_err(|_| bad(format!("bad rgba '{v}'")))?;
                rgba = Some(
                    <[f32; 4]>::try_from(vals.as_slice())
                        .map_err(|_| bad("rgba needs 4 numbers".into()))?,
                );
            }
            other => return Err(bad(format!("unknown key '{other}'"))),
        }
    }
    Ok(Rule {
        when: when.ok_or_else(|| bad("no when=".into()))?,
        geoms,
        rgba: rgba.ok_or_else(|| bad("no rgba=".into()))?,
    })
}
