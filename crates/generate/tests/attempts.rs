//! The generator's parts on a real source (the shipped click_mouse sample, replayed in
//! MuJoCo): the transform is exact, a subtask whose end never comes is a named failure,
//! and an attempt is a function of its index and seed.

use dexjoco_core::{Episode, Pose, TaskSpec};
use dexjoco_generate::{AttemptOptions, SourceDemo, attempt, carry};
use dexjoco_sim::{SceneSource, TaskEnv, load_task_scene};
use rand::{Rng, SeedableRng};

fn sample(task: &str) -> Episode {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../datasets/demos")
        .join(task)
        .join("episode_000000");
    let spec = TaskSpec::builtin(task).unwrap();
    dexjoco_formats::raw::read_raw_episode(&dir, spec)
        .unwrap()
        .episode
}

fn close(a: &Pose, b: &Pose, tol: f64) -> bool {
    a.distance(b) < tol && a.angle_to(b) < tol
}

#[test]
fn carrying_a_segment_is_exact() {
    let spec = TaskSpec::builtin("click_mouse").unwrap();
    let scene = load_task_scene(&SceneSource::BuiltIn, spec).unwrap();
    let ep = sample("click_mouse");
    let demo = SourceDemo::prepare(&scene, spec, &ep, 0).unwrap();
    let actions = ep.array(Episode::ACTION).unwrap();
    for seg in &demo.segments {
        // In its own object frame, a segment is the source's targets: the pose part of
        // its action rows, to 1e-9.
        let own = carry(seg, &seg.object_pose);
        assert_eq!(own.len(), seg.last - seg.start + 1);
        for (k, step) in own.iter().enumerate() {
            let row = actions.row(seg.start + k);
            let given = Pose::from_slice(&row[..7]);
            assert!(
                close(&step[0].pose, &given, 1e-9),
                "segment {} step {}: {:?} vs action {:?}",
                seg.subtask,
                seg.start + k,
                step[0].pose,
                given
            );
        }
        // Elsewhere, every target keeps its pose relative to the object, to 1e-9, and
        // carrying it back gives the source's targets.
        let moved = Pose::new(
            [
                seg.object_pose.pos[0] + 0.07,
                seg.object_pose.pos[1] - 0.05,
                seg.object_pose.pos[2],
            ],
            dexjoco_core::pose::qmul(
                [0.9238795325112867, 0.0, 0.0, 0.3826834323650898],
                seg.object_pose.quat,
            ),
        );
        let there = carry(seg, &moved);
        for (k, (t, s)) in there.iter().zip(&seg.targets).enumerate() {
            let rel_new = moved.relative(&t[0].pose);
            let rel_src = seg.object_pose.relative(&s[0].pose);
            assert!(close(&rel_new, &rel_src, 1e-9), "step {k}");
            assert_eq!(t[0].hand, s[0].hand, "hands as recorded");
        }
        let back_seg = dexjoco_generate::Segment {
            object_pose: moved,
            targets: there,
            ..seg.clone()
        };
        for (t, s) in carry(&back_seg, &seg.object_pose).iter().zip(&seg.targets) {
            assert!(close(&t[0].pose, &s[0].pose, 1e-9));
        }
    }
}

#[test]
fn a_subtask_whose_end_never_comes_is_a_named_failure() {
    let spec = TaskSpec::builtin("click_mouse").unwrap();
    let scene = load_task_scene(&SceneSource::BuiltIn, spec).unwrap();
    let demo = SourceDemo::prepare(&scene, spec, &sample("click_mouse"), 0).unwrap();
    // The same task, but its first subtask ends only when the mouse's button has moved
    // a metre: never.
    let text = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../schemas/tasks/click_mouse.toml"),
    )
    .unwrap()
    .replace(
        "id = \"push_mouse\"\ntext = \"move the mouse onto the pad\"\narm = \"single\"\nobject = \"mouse\"\nend = \"on_pad\"",
        "id = \"push_mouse\"\ntext = \"move the mouse onto the pad\"\narm = \"single\"\nobject = \"mouse\"\nend = \"never\"",
    )
    + "\n[nodes.never]\nkind = \"joint_above_reset\"\njoint = { sensor = \"mouse_joint0_pos\" }\ndelta = 1.0\n";
    let never = TaskSpec::from_toml_str(&text, "click_mouse (never)").unwrap();
    assert_eq!(never.subtasks[0].end, "never");
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let reset = TaskEnv::sample_initial_state(&scene, &never, &mut || rng.random()).unwrap();
    let options = AttemptOptions {
        grace_steps: 15,
        ..AttemptOptions::default()
    };
    let a = attempt(&scene, &never, &[demo], reset, 0, 3, &options).unwrap();
    let failure = a.failure.expect("the attempt fails");
    assert_eq!(failure.subtask.as_deref(), Some("push_mouse"));
    assert!(
        failure.reason.contains("'never'") && failure.reason.contains("15 steps"),
        "{}",
        failure.reason
    );
    assert!(a.planned.success_at.is_none());
    // It stopped right there: the segment, its bridge and the grace steps.
    let p = &a.provenance[0];
    let seg_len = p.source_steps[1] - p.source_steps[0] + 1;
    assert_eq!(failure.step, p.bridge_steps + seg_len + 15);
    assert_eq!(a.provenance.len(), 1, "the next subtask never started");
}

#[test]
fn an_attempt_depends_on_its_index_and_seed_only() {
    let spec = TaskSpec::builtin("click_mouse").unwrap();
    let scene = load_task_scene(&SceneSource::BuiltIn, spec).unwrap();
    let demos: Vec<SourceDemo> = (0..2)
        .map(|_| SourceDemo::prepare(&scene, spec, &sample("click_mouse"), 0).unwrap())
        .collect();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
    let reset = TaskEnv::sample_initial_state(&scene, spec, &mut || rng.random()).unwrap();
    let run = |index| {
        attempt(
            &scene,
            spec,
            &demos,
            reset.clone(),
            index,
            9,
            &AttemptOptions::default(),
        )
        .unwrap()
    };
    let (a, b) = (run(4), run(4));
    assert_eq!(a.planned.episode, b.planned.episode);
    assert_eq!(a.provenance, b.provenance);
    assert!(a.planned.success_at.is_some(), "{:?}", a.failure);
    // The generated episode starts from the reset it was given (its objects and table;
    // the robot at its home pose).
    let states = a.planned.episode.array(Episode::STATE).unwrap();
    let layout = spec.state_layout();
    for p in &spec.placement {
        let f = layout.get(&format!("{}.pose", p.object)).unwrap();
        let range = f.start..f.start + f.len;
        assert_eq!(states.row(0)[range.clone()], reset[range], "{}", p.object);
    }
}
