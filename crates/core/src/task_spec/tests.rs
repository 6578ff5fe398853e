//! Tests of task specs: the shipped files, the schema, the checks.

use super::*;
use std::path::PathBuf;

fn schemas_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../schemas")
}

/// The 11 DexJoCo tasks with their state widths (dexjoco-raw-format.md).
const TASKS: [(&str, usize); 11] = [
    ("bimanual_assembly", 61),
    ("bimanual_hanoi", 50),
    ("bimanual_microwave_cook", 61),
    ("bimanual_photograph", 61),
    ("bimanual_unlock_ipad", 61),
    ("click_mouse", 31),
    ("fold_glasses", 38),
    ("hammer_nail", 38),
    ("pick_bucket", 38),
    ("pinch_tongs", 31),
    ("water_plant", 38),
];

#[test]
fn every_task_spec_loads_and_validates() {
    let specs = TaskSpec::load_dir(&schemas_dir().join("tasks")).unwrap();
    let ids: Vec<_> = specs
        .iter()
        .map(|s| (s.id.as_str(), s.state.width))
        .collect();
    assert_eq!(ids, TASKS);
    for s in &specs {
        let order = s.evaluation_order().unwrap();
        assert_eq!(order.len(), s.nodes.len(), "{}", s.id);
        // Inputs come before the nodes that read them.
        for (i, name) in order.iter().enumerate() {
            for input in s.nodes[name].inputs() {
                let base = input.split('.').next().unwrap();
                let j = order.iter().position(|n| n == base).unwrap();
                assert!(j < i, "{}: {base} after {name}", s.id);
            }
        }
        assert!(!s.scene_names().is_empty());
        // The four constraint kinds and mechanics appear as primitives, never as code.
        let cap = if s.setup == ArmSetup::Bimanual {
            46
        } else {
            23
        };
        assert_eq!(s.setup.proprio_dim(), cap);
    }
    // Some fixed facts.
    let mouse = specs.iter().find(|s| s.id == "click_mouse").unwrap();
    assert_eq!(mouse.step_cap, 1200);
    assert_eq!(mouse.state_layout().get("mouse.pose").unwrap().start, 23);
    let hanoi = specs.iter().find(|s| s.id == "bimanual_hanoi").unwrap();
    assert_eq!(hanoi.state_layout().get("dh").unwrap().start, 49);
}

/// The committed JSON Schema is exactly the one generated from the serde types, so
/// schema and reader agree. Regenerate with `DEXJOCO_UPDATE_SCHEMA=1 cargo test`.
#[test]
fn json_schema_matches_the_types() {
    // Keys sorted, whatever serde_json's `preserve_order` feature (which other crates
    // of the workspace turn on) makes of map order.
    fn sorted(v: &serde_json::Value) -> serde_json::Value {
        match v {
            serde_json::Value::Object(m) => {
                let mut keys: Vec<&String> = m.keys().collect();
                keys.sort();
                serde_json::Value::Object(
                    keys.into_iter()
                        .map(|k| (k.clone(), sorted(&m[k])))
                        .collect(),
                )
            }
            serde_json::Value::Array(a) => serde_json::Value::Array(a.iter().map(sorted).collect()),
            other => other.clone(),
        }
    }
    let path = schemas_dir().join("task-spec.schema.json");
    let generated = sorted(&TaskSpec::json_schema());
    if std::env::var_os("DEXJOCO_UPDATE_SCHEMA").is_some() {
        fs_err::write(
            &path,
            serde_json::to_string_pretty(&generated).unwrap() + "\n",
        )
        .unwrap();
    }
    let committed: serde_json::Value =
        serde_json::from_str(&fs_err::read_to_string(&path).unwrap_or_default())
            .unwrap_or_default();
    assert!(
        committed == generated,
        "{} is stale: run DEXJOCO_UPDATE_SCHEMA=1 cargo test -p dexjoco-core",
        path.display()
    );
    // Every spec, as JSON, uses only properties the schema declares at the top level.
    let schema = TaskSpec::json_schema();
    let props = schema["properties"].as_object().unwrap();
    for s in TaskSpec::load_dir(&schemas_dir().join("tasks")).unwrap() {
        let v = serde_json::to_value(&s).unwrap();
        for k in v.as_object().unwrap().keys() {
            assert!(props.contains_key(k), "{}: {k} not in the schema", s.id);
        }
        for r in schema["required"].as_array().unwrap() {
            assert!(
                v.get(r.as_str().unwrap()).is_some(),
                "{}: {r} missing",
                s.id
            );
        }
        // Round trip: what we write reads back the same.
        let back: TaskSpec = serde_json::from_value(v).unwrap();
        assert_eq!(back, s);
    }
}

fn minimal(extra: &str) -> String {
    format!(
        r#"
id = "t"
name = "T"
setup = "single_arm"
scene = "s.xml"
prompt = "p"
step_cap = 10
success = "done"
cameras = [{{ key = "front", camera = "front" }}]
[state]
width = 24
objects = []
{extra}
"#
    )
}

#[test]
fn unknown_keys_and_bad_references_are_refused() {
    let ok = minimal(
        "[nodes.done]\nkind = \"all\"\nof = [\"x\"]\n[nodes.x]\nkind = \"not\"\nof = \"done2\"\n[nodes.done2]\nkind = \"latch\"\nset = \"x\"\n",
    );
    // x -> done2 -> x is a cycle.
    let e = TaskSpec::from_toml_str(&ok, "t").unwrap_err().to_string();
    assert!(e.contains("depends on itself"), "{e}");

    let typo = minimal("[nodes.done]\nkind = \"held\"\nof = \"done\"\nstep = 3\n");
    let e = TaskSpec::from_toml_str(&typo, "t").unwrap_err().to_string();
    assert!(e.contains("step"), "{e}");

    let unknown = minimal("[nodes.done]\nkind = \"not\"\nof = \"nothing\"\n");
    let e = TaskSpec::from_toml_str(&unknown, "t")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("unknown node 'nothing'") && e.contains("field 'nodes.done'"),
        "{e}"
    );

    let port = minimal(
        "[nodes.a]\nkind = \"held\"\nof = \"b\"\nsteps = 2\n[nodes.b]\nkind = \"not\"\nof = \"a.depth\"\n[nodes.done]\nkind = \"not\"\nof = \"a\"\n",
    );
    let e = TaskSpec::from_toml_str(&port, "t").unwrap_err().to_string();
    assert!(e.contains("no output 'depth'"), "{e}");

    let width = minimal("[nodes.done]\nkind = \"joint_threshold\"\njoint = { qpos = \"j\" }\nop = \"gt\"\nvalue = 1.0\n")
        .replace("width = 24", "width = 23");
    let e = TaskSpec::from_toml_str(&width, "t")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("task spec 't'") && e.contains("field 'state.width'"),
        "{e}"
    );

    let top = minimal(
        "[nodes.done]\nkind = \"any\"\nof = [\"e\"]\n[nodes.e]\nkind = \"joint_threshold\"\njoint = { qpos = \"j\" }\nop = \"gt\"\nvalue = 1.0\n",
    ) + "\n[extra]\nx = 1\n";
    assert!(TaskSpec::from_toml_str(&top, "t").is_err());
}

#[test]
fn privileged_fields_cover_the_state_after_proprioception() {
    for t in builtin_specs().values() {
        let p = t.privileged();
        assert_eq!(p.first().unwrap().start, t.setup.proprio_dim(), "{}", t.id);
        assert_eq!(p.last().unwrap().start, t.dh_column());
        assert_eq!(t.state_layout().column_name(t.dh_column()), "dh[0]");
    }
    let hanoi = TaskSpec::builtin("bimanual_hanoi").unwrap();
    assert_eq!(hanoi.privileged()[0].kind, PrivilegedKind::Position);
}

#[test]
fn every_task_has_subtasks_ending_on_its_success() {
    for s in TaskSpec::load_dir(&schemas_dir().join("tasks")).unwrap() {
        assert!(
            s.subtasks.len() >= 2,
            "{}: {} subtasks",
            s.id,
            s.subtasks.len()
        );
        // The last subtask of the list ends on the task's success.
        assert_eq!(s.subtasks.last().unwrap().end, s.success, "{}", s.id);
        let before = s.subtask_predecessors();
        assert!(before[0].is_empty(), "{}", s.id);
        for (i, b) in before.iter().enumerate() {
            assert!(
                b.iter().all(|&j| j < i),
                "{}: subtask {i} waits for a later one",
                s.id
            );
        }
    }
}

#[test]
fn a_subtask_that_a_spec_gets_wrong_is_a_named_spec_error() {
    let base = TaskSpec::builtin("bimanual_assembly").unwrap().clone();
    let check = |edit: &dyn Fn(&mut TaskSpec), expect: &[&str]| {
        let mut s = base.clone();
        edit(&mut s);
        let e = s.validate().unwrap_err().to_string();
        for x in expect {
            assert!(e.contains(x), "expected '{x}' in: {e}");
        }
    };
    check(
        &|s| s.subtasks[0].end = "no_such_node".into(),
        &[
            "bimanual_assembly",
            "subtasks[0].end",
            "'no_such_node' is not a node",
        ],
    );
    check(
        &|s| s.subtasks[0].end = "hanoi.on_goal".into(),
        &["subtasks[0].end", "is not a node"],
    );
    // The left arm's subtask ending on a node that reads the right hand.
    check(
        &|s| s.subtasks[1].end = "peg_held".into(),
        &[
            "subtasks[1].end",
            "(left arm) reads the right hand through node 'peg_grasped'",
        ],
    );
    check(
        &|s| s.subtasks[0].arm = SubtaskArm::Single,
        &["subtasks[0].arm", "'single' in a two-arm task"],
    );
    check(
        &|s| s.subtasks[0].object = "hammer".into(),
        &["subtasks[0].object", "unknown object 'hammer'"],
    );
    check(&|s| s.subtasks[1].id = "grasp_peg".into(), &["given twice"]);
    check(
        &|s| s.subtasks[1].after = vec!["insert_peg".into()],
        &[
            "subtasks[1].after",
            "'insert_peg' is not an earlier subtask",
        ],
    );
    check(
        &|s| s.subtasks[2].after = vec!["grasp_peg".into()],
        &["'grasp_peg' is of the same arm"],
    );
    // A grasp node of the wrong hand for the setup.
    let mut single = TaskSpec::builtin("hammer_nail").unwrap().clone();
    if let Some(Node::Grasp { hand, .. }) = single.nodes.get_mut("hammer_grasped") {
        *hand = Hand::Left;
    }
    let e = single.validate().unwrap_err().to_string();
    assert!(
        e.contains("nodes.hammer_grasped") && e.contains("hand must be `single`"),
        "{e}"
    );
}
