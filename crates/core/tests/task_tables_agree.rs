//! The per-task facts ingest validates with (`TASKS`) and the task specs
//! (`schemas/tasks/*.toml`) must not drift apart.

use dexjoco_core::{TASKS, TaskSpec, task_info};

#[test]
fn task_table_and_task_specs_agree() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../schemas/tasks");
    let specs = TaskSpec::load_dir(&dir).expect("task specs load");
    assert_eq!(specs.len(), TASKS.len(), "11 specs, 11 table rows");
    for spec in &specs {
        let info = task_info(&spec.id).unwrap_or_else(|| panic!("{} is not in TASKS", spec.id));
        assert_eq!(info.setup, spec.setup, "{}: setup", spec.id);
        assert_eq!(
            info.state_dim,
            spec.state_layout().width(),
            "{}: state width",
            spec.id
        );
        assert_eq!(info.step_cap, spec.step_cap, "{}: step cap", spec.id);
        assert_eq!(info.prompt, spec.prompt, "{}: prompt", spec.id);
    }
}
