//! The built-in task scenes, authored by this project and embedded in the binary: the
//! arena (`assets/builtin/arena.xml`), the robot layout of the task's setup (one
//! Panda + Allegro from the `robot.xml` template, or two), and the task's objects
//! (`assets/builtin/objects/<task_id>.xml`). Each part is a standalone `<mujoco>`
//! document; the scene is their sections spliced into one document (MuJoCo allows a
//! section to repeat), compiled from memory, so it loads from any working directory.

use dexjoco_core::{ArmSetup, TaskSpec};

use crate::error::SimError;
use crate::scene::Scene;

mod objects {
    include!(concat!(env!("OUT_DIR"), "/builtin_objects.rs"));
}

const ARENA: &str = include_str!("../assets/builtin/arena.xml");
const ROBOT: &str = include_str!("../assets/builtin/robot.xml");
const LAYOUT_SINGLE: &str = include_str!("../assets/builtin/layout_single_arm.xml");
const LAYOUT_BIMANUAL: &str = include_str!("../assets/builtin/layout_bimanual.xml");

/// The ids of the tasks that have a built-in object fragment, sorted.
pub fn builtin_tasks() -> Vec<&'static str> {
    objects::OBJECTS.iter().map(|(id, _)| *id).collect()
}

/// The object fragment of a task, if it has one.
pub fn object_fragment(task_id: &str) -> Option<&'static str> {
    objects::OBJECTS
        .iter()
        .find(|(id, _)| *id == task_id)
        .map(|(_, xml)| *xml)
}

/// The contents of a `<mujoco>` document: everything between its opening tag and
/// `</mujoco>`.
fn inner<'a>(xml: &'a str, label: &str) -> Result<&'a str, SimError> {
    let bad = |what: &str| SimError::Load {
        path: label.into(),
        message: format!("built-in scene part: {what}"),
    };
    let open = xml
        .find("<mujoco")
        .ok_or_else(|| bad("no <mujoco> element"))?;
    let body = open
        + xml[open..]
            .find('>')
            .ok_or_else(|| bad("unclosed <mujoco"))?
        + 1;
    let end = xml.rfind("</mujoco>").ok_or_else(|| bad("no </mujoco>"))?;
    if end < body {
        return Err(bad("empty <mujoco/> element"));
    }
    Ok(&xml[body..end])
}

/// One robot instance from the template: `suffix` "", "_right" or "_left".
fn robot(suffix: &str, base: &str, left: bool, kp: &str) -> String {
    let (fa, fc) = if left { ("rf", "ff") } else { ("ff", "rf") };
    let (hand, th_pos, th_quat, th0, th1, thp) = if left {
        (
            "allegro_left",
            "-0.0182 -0.019333 -0.045987",
            "0.477714 0.521334 -0.521334 0.477714",
            "1 0 0",
            "0 0 -1",
            "-0.027 -0.005 0.0399",
        )
    } else {
        (
            "allegro_right",
            "-0.0182 0.019333 -0.045987",
            "0.477714 -0.521334 -0.521334 -0.477714",
            "-1 0 0",
            "0 0 1",
            "-0.027 0.005 0.0399",
        )
    };
    ROBOT
        .replace("{S}", suffix)
        .replace("{HAND}", hand)
        .replace("{BASE}", base)
        .replace("{KP}", kp)
        .replace("{FA}", fa)
        .replace("{FC}", fc)
        .replace("{TH_POS}", th_pos)
        .replace("{TH_QUAT}", th_quat)
        .replace("{TH0_AXIS}", th0)
        .replace("{TH1_AXIS}", th1)
        .replace("{THP_POS}", thp)
}

/// The MJCF text of a task's built-in scene.
pub fn scene_xml(spec: &TaskSpec) -> Result<String, SimError> {
    let objects = object_fragment(&spec.id).ok_or_else(|| SimError::NoBuiltinScene {
        task: spec.id.clone(),
        builtin: builtin_tasks().iter().map(|t| t.to_string()).collect(),
    })?;
    let mut parts: Vec<(String, String)> = vec![("arena.xml".into(), ARENA.into())];
    match spec.setup {
        ArmSetup::SingleArm => {
            parts.push(("layout_single_arm.xml".into(), LAYOUT_SINGLE.into()));
            parts.push(("robot.xml".into(), robot("", "-0.8 0 0.924", false, "2")));
        }
        ArmSetup::Bimanual => {
            parts.push(("layout_bimanual.xml".into(), LAYOUT_BIMANUAL.into()));
            parts.push((
                "robot.xml (right)".into(),
                robot("_right", "-0.8 -0.4 0.924", false, "1"),
            ));
            parts.push((
                "robot.xml (left)".into(),
                robot("_left", "-0.8 0.4 0.924", true, "1"),
            ));
        }
    }
    parts.push((format!("objects/{}.xml", spec.id), objects.into()));
    let mut xml = format!("<mujoco model=\"builtin_{}\">\n", spec.id);
    for (label, text) in &parts {
        xml.push_str(&format!("<!-- {label} -->\n"));
        xml.push_str(inner(text, label)?);
        xml.push('\n');
    }
    xml.push_str("</mujoco>\n");
    Ok(xml)
}

/// Compiles a task's built-in scene.
pub fn load_builtin(spec: &TaskSpec) -> Result<Scene, SimError> {
    let xml = scene_xml(spec)?;
    let label = format!("<built-in {}>", spec.id);
    Scene::from_xml_str(&xml, &label)
}
