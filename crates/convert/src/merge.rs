//! Multi-task merge of one-arm and two-arm episodes into the two-arm layout.
//!
//! The reference converter pads one-arm action/state with zeros at the end, which lines
//! the one-arm action up with the right arm (actions are `[right, left]`) but not the
//! state: the two-arm proprioception is `[right TCP 7, left TCP 7, right hand 16, left
//! hand 16]`, so padded one-arm hand joints land on the left TCP. Here every one-arm
//! field goes to its right-arm slot:
//!
//! - `action_rotvec` 22 -> 44: `[pos 3, rotvec 3, hand 16]` -> columns 0..22; the left
//!   arm's slots are zero (rotation vector zero = identity);
//! - `action` 23 -> 46: columns 0..23; the left arm's quaternion is the identity
//!   `[1, 0, 0, 0]`, its other slots zero;
//! - proprioceptive `state` 23 -> 46: TCP pose -> 0..7, hand -> 14..30; the left TCP
//!   quaternion (10..14) is the identity, the rest zero.
//!
//! The DexJoCo one-arm robot is the right arm of the two-arm setup (same Panda +
//! right Allegro hand), so the right-arm slots are its natural place.

use dexjoco_core::{ArmSetup, FrameArray, HAND_DOF, POSE_DIM};

/// One-arm action (`action` 23 or `action_rotvec` 22 columns) in the two-arm layout.
pub fn action_to_bimanual(a: &FrameArray) -> Option<FrameArray> {
    let w = a.width();
    let rotvec = if w == ArmSetup::SingleArm.action_rotvec_dim() {
        true
    } else if w == ArmSetup::SingleArm.action_dim() {
        false
    } else {
        return None;
    };
    let mut data = Vec::with_capacity(a.len() * 2 * w);
    for i in 0..a.len() {
        data.extend_from_slice(a.row(i));
        let start = data.len();
        data.resize(start + w, 0.0);
        if !rotvec {
            data[start + 3] = 1.0; // left arm: identity quaternion wxyz
        }
    }
    Some(FrameArray::new(2 * w, data).expect("whole rows"))
}

/// One-arm proprioceptive state (23 columns: TCP pose 7, hand 16) in the two-arm layout.
pub fn state_to_bimanual(s: &FrameArray) -> Option<FrameArray> {
    if s.width() != POSE_DIM + HAND_DOF {
        return None;
    }
    let w2 = 2 * (POSE_DIM + HAND_DOF);
    let mut data = vec![0.0; s.len() * w2];
    for i in 0..s.len() {
        let r = s.row(i);
        let out = &mut data[i * w2..(i + 1) * w2];
        out[..POSE_DIM].copy_from_slice(&r[..POSE_DIM]);
        out[POSE_DIM + 3] = 1.0; // left TCP: identity quaternion wxyz
        out[2 * POSE_DIM..2 * POSE_DIM + HAND_DOF].copy_from_slice(&r[POSE_DIM..]);
    }
    Some(FrameArray::new(w2, data).expect("whole rows"))
}
