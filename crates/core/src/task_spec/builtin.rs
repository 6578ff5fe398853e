//! The task specs shipped in `schemas/tasks/`: embedded at build time, parsed once per
//! process, looked up by task id with [`TaskSpec::builtin`].

use std::collections::BTreeMap;
use std::sync::OnceLock;

use super::TaskSpec;

/// The task specs shipped in `schemas/tasks/`, embedded at build time: (task id, TOML).
pub const BUILTIN_SPEC_FILES: [(&str, &str); 11] = {
    macro_rules! specs {
        ($($id:literal),*) => {
            [$(($id, include_str!(concat!("../../../../schemas/tasks/", $id, ".toml")))),*]
        };
    }
    specs!(
        "bimanual_assembly",
        "bimanual_hanoi",
        "bimanual_microwave_cook",
        "bimanual_photograph",
        "bimanual_unlock_ipad",
        "click_mouse",
        "fold_glasses",
        "hammer_nail",
        "pick_bucket",
        "pinch_tongs",
        "water_plant"
    )
};

/// The shipped specs by task id, parsed on first use. An embedded spec is checked by this
/// crate's tests, so failing to parse one is a build defect (a panic names it).
pub(crate) fn builtin_specs() -> &'static BTreeMap<String, TaskSpec> {
    static BUILTIN: OnceLock<BTreeMap<String, TaskSpec>> = OnceLock::new();
    BUILTIN.get_or_init(|| {
        BUILTIN_SPEC_FILES
            .iter()
            .map(|(id, text)| {
                let spec = TaskSpec::from_toml_str(text, &format!("schemas/tasks/{id}.toml"))
                    .unwrap_or_else(|e| panic!("embedded task spec {id}: {e}"));
                ((*id).to_owned(), spec)
            })
            .collect()
    })
}

impl TaskSpec {
    /// The shipped spec of a task (embedded from `schemas/tasks/`, parsed once per
    /// process); `None` for an unknown id.
    pub fn builtin(id: &str) -> Option<&'static Self> {
        builtin_specs().get(id)
    }
}
