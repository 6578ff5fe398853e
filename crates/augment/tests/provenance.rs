//! Each replay records where it was made (CPU model and flags, the programs' versions) in
//! its `replay.json`; the report lists each place once and warns when the replays were
//! made in more than one (MuJoCo's floating point depends on the CPU).

use dexjoco_augment::{AugmentConfig, REPORT_MD, augment};
use dexjoco_core::NoProgress;
use dexjoco_render::RenderSettings;

fn config(out: &std::path::Path) -> AugmentConfig {
    AugmentConfig {
        replays: 2,
        settings: RenderSettings {
            width: 32,
            height: 32,
            ..RenderSettings::default()
        },
        keep_failed: true,
        max_frames: Some(4),
        contact_sheet: false,
        extend_steps: 0,
        ..AugmentConfig::new(
            vec![
                dexjoco_testkit::workspace_root().join("datasets/demos/click_mouse/episode_000000"),
            ],
            out,
        )
    }
}

#[test]
fn replays_record_where_they_were_made_and_the_report_warns_of_a_mix() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("aug");
    let c = config(&out);
    let report = augment(&c, &NoProgress).unwrap();
    assert_eq!(report.replays.len(), 2);
    let here = dexjoco_augment::this_machine();
    let cpuinfo = fs_err::read_to_string("/proc/cpuinfo").unwrap();
    assert!(cpuinfo.contains(&here.cpu_model), "{here:?}");
    assert_eq!(here.versions, *dexjoco_augment::current_versions());
    assert_eq!(report.made_on.len(), 1);
    assert_eq!(
        (&report.made_on[0].provenance, report.made_on[0].replays),
        (here, 2)
    );
    let record_path = out.join("click_mouse/episode_000000__r01/replay.json");
    let mut record: serde_json::Value =
        serde_json::from_slice(&fs_err::read(&record_path).unwrap()).unwrap();
    assert_eq!(record["made_on"]["cpu_model"], here.cpu_model.as_str());
    assert_eq!(
        record["made_on"]["versions"]["mujoco"],
        here.versions.mujoco.as_str()
    );
    let md = fs_err::read_to_string(out.join(REPORT_MD)).unwrap();
    assert!(
        md.contains("## Where the replays were made") && !md.contains("**Warning:**"),
        "{md}"
    );

    // As if one replay had been made by a shard on another machine.
    record["made_on"]["cpu_model"] = "Another CPU".into();
    fs_err::write(&record_path, serde_json::to_vec_pretty(&record).unwrap()).unwrap();
    let report = augment(&c, &NoProgress).unwrap();
    assert_eq!(report.rendered_now, 0);
    let models: Vec<&str> = report
        .made_on
        .iter()
        .map(|m| m.provenance.cpu_model.as_str())
        .collect();
    assert!(
        models.contains(&"Another CPU") && models.len() == 2,
        "{models:?}"
    );
    let md = fs_err::read_to_string(out.join(REPORT_MD)).unwrap();
    assert!(
        md.contains("**Warning:** the replays were made in 2 different places"),
        "{md}"
    );
}
