//! The planners' hand presets, each named once: Allegro hand targets (16 values: index,
//! middle and ring finger, each its abduction then three flexions, then the thumb's four)
//! built by [`hand`] from named finger poses. Presets shared by several planners sit at
//! the top; those of one planner in a module named after its task.

use dexjoco_core::HAND_DOF;

use dexjoco_sim::THUMB_HOME;

/// One hand's 16 joint targets.
pub(crate) type Hand = [f64; HAND_DOF];
/// One finger's (or the thumb's) 4 joint targets.
pub(crate) type Finger = [f64; 4];

/// The hand from its index, middle and ring fingers and its thumb.
pub(crate) const fn hand(index: Finger, middle: Finger, ring: Finger, thumb: Finger) -> Hand {
    let mut h = [0.0; HAND_DOF];
    let all = [index, middle, ring, thumb];
    let mut f = 0;
    while f < 4 {
        let mut j = 0;
        while j < 4 {
            h[4 * f + j] = all[f][j];
            j += 1;
        }
        f += 1;
    }
    h
}

/// The hand whose three fingers all take `finger`, with `thumb`.
pub(crate) const fn fingers(finger: Finger, thumb: Finger) -> Hand {
    hand(finger, finger, finger, thumb)
}

/// A straight finger.
pub(crate) const STRAIGHT: Finger = [0.0; 4];
/// A finger half curled.
pub(crate) const HALF_CURLED: Finger = [0.0, 0.4, 0.4, 0.3];
/// A finger closed (on an object, or on the thumb).
pub(crate) const CLOSED: Finger = [0.0, 1.2, 1.2, 1.0];
/// A finger curled away, out of the way of the others.
pub(crate) const TUCKED: Finger = [0.0, 1.6, 1.7, 1.6];
/// The thumb at its home (the controller's [`THUMB_HOME`]).
pub(crate) const THUMB_AT_HOME: Finger = [THUMB_HOME, 0.0, 0.0, 0.0];
/// The thumb turned under the palm, open.
pub(crate) const THUMB_UNDER_OPEN: Finger = [0.8, 0.0, 0.2, 0.2];
/// The thumb turned under the palm and closed toward the fingers.
pub(crate) const THUMB_UNDER_CLOSED: Finger = [1.4, 0.5, 0.8, 0.8];
/// The thumb folded up under the palm (its tip about 5 cm below the TCP).
pub(crate) const THUMB_FOLDED_UP: Finger = [1.4, 0.5, 1.6, 1.6];

/// The cage pinch's approach pose: fingers half curled, the thumb turned under the palm
/// but open.
pub(crate) const OPEN: Hand = fingers(HALF_CURLED, THUMB_UNDER_OPEN);
/// The cage pinch closed: fingers and thumb closed on each other, so an object between
/// them is squeezed (targets past contact give the force).
pub(crate) const CLOSE: Hand = fingers(CLOSED, THUMB_UNDER_CLOSED);
/// Index finger curled to point down, the others tucked away, the thumb at home.
pub(crate) const POINT_HAND: Hand = hand([0.0, 1.3, 0.9, 0.3], TUCKED, TUCKED, THUMB_AT_HOME);
/// Straight fingers and the thumb at home.
pub(crate) const FLAT_HAND: Hand = fingers(STRAIGHT, THUMB_AT_HOME);
/// Straight index finger, middle and ring tucked away, the thumb at home: with the hand
/// pitched fingers-down, the index fingertip is a probe well below the rest of the hand.
pub(crate) const INDEX_HAND: Hand = hand(STRAIGHT, TUCKED, TUCKED, THUMB_AT_HOME);

/// hammer_nail's wrap grasp.
pub(crate) mod hammer_nail {
    use super::{Hand, fingers};

    /// The wrap's approach: fingers nearly straight, the thumb turned under the palm, open.
    pub(crate) const WRAP_OPEN: Hand = fingers([0.0, 0.2, 0.1, 0.1], [1.2, 0.0, 0.0, 0.0]);
    /// The wrap closed: fingers curled over and under the handle, the thumb pressing its
    /// near side.
    pub(crate) const WRAP: Hand = fingers([0.0, 1.5, 1.5, 1.3], [1.3, 0.6, 1.0, 1.0]);
}

/// bimanual_microwave_cook's door and clamp hands.
pub(crate) mod microwave_cook {
    use super::{
        HALF_CURLED, Hand, STRAIGHT, THUMB_FOLDED_UP, THUMB_UNDER_CLOSED, TUCKED, fingers, hand,
    };

    /// The thumb folded up under the palm and bent back at its base.
    const THUMB_FOLDED_BACK: [f64; 4] = [1.4, -0.1, 1.6, 1.6];

    /// The left hand hooking the handle: fingers almost straight, the thumb folded up
    /// under the palm.
    pub(crate) const HOOK: Hand = fingers([0.0, 0.1, 0.1, 0.1], THUMB_FOLDED_BACK);
    /// The left hand pushing the door shut: fingers curled a little so that their tips,
    /// not the palm, touch the door.
    pub(crate) const SHUT_HAND: Hand = fingers([0.0, 0.5, 0.2, 0.1], THUMB_FOLDED_BACK);
    /// The clamp's approach: fingers half curled, the thumb already turned under the palm
    /// (closing is [`super::CLOSE`]: the same thumb, the fingers curled over the hot dog).
    pub(crate) const CLAMP_OPEN: Hand = fingers(HALF_CURLED, THUMB_UNDER_CLOSED);
    /// Letting go: straight fingers, the thumb folded up under the palm (its tip 5 cm below
    /// the TCP).
    pub(crate) const RELEASE: Hand = fingers(STRAIGHT, THUMB_FOLDED_UP);
    /// Straight index finger, middle and ring curled, the thumb folded up under the palm.
    pub(crate) const PRESS: Hand = hand(STRAIGHT, TUCKED, TUCKED, THUMB_FOLDED_UP);
}

/// pick_bucket's food pinch and handle hooks.
pub(crate) mod pick_bucket {
    use super::{CLOSED, Hand, THUMB_AT_HOME, THUMB_UNDER_OPEN, fingers};

    /// The fingers closed, the thumb still open.
    pub(crate) const HOOK: Hand = fingers(CLOSED, THUMB_UNDER_OPEN);
    /// Fingers pointing straight down (the proximal links vertical), the thumb at home.
    pub(crate) const DOWN: Hand = fingers([0.0, 1.4, 0.2, 0.0], THUMB_AT_HOME);
    /// The fingers hooked (distal links curled back toward the palm), the thumb at home.
    pub(crate) const HOOK_DOWN: Hand = fingers([0.0, 1.57, 1.0, 0.8], THUMB_AT_HOME);
}

/// water_plant's bottle grasp and trigger presses.
pub(crate) mod water_plant {
    use super::{
        CLOSED, HALF_CURLED, Hand, STRAIGHT, THUMB_AT_HOME, THUMB_UNDER_CLOSED, THUMB_UNDER_OPEN,
        hand,
    };

    /// The ring finger lying over the bottle's body.
    const RING_OVER: [f64; 4] = [0.0, 0.2, 0.3, 0.2];

    /// Fingers half curled, thumb turned under the palm but open, the index straight: the
    /// approach pose.
    pub(crate) const OPEN: Hand = hand(STRAIGHT, HALF_CURLED, HALF_CURLED, THUMB_UNDER_OPEN);
    /// Middle, ring and thumb closed on the body; the index finger straight.
    pub(crate) const HOLD: Hand = hand(STRAIGHT, CLOSED, CLOSED, THUMB_UNDER_CLOSED);
    /// As [`HOLD`], the index finger curled onto the trigger.
    pub(crate) const PULL: Hand = hand([0.0, 0.9, 0.1, 0.1], CLOSED, CLOSED, THUMB_UNDER_CLOSED);
    /// Index and middle hooked down (tips ~0.08 below and ~0.13 ahead of the TCP,
    /// measured), the ring finger lying over the body, the thumb at home.
    pub(crate) const AIM: Hand = {
        let f = [0.0, 0.0, 1.0, 0.6];
        hand(f, f, RING_OVER, THUMB_AT_HOME)
    };
    /// As [`AIM`], index and middle curled (mostly the two outer joints, so the tips sweep
    /// back toward the body at the trigger's height rather than down under it).
    pub(crate) const PRESS: Hand = {
        let f = [0.0, 0.4, 1.709, 1.618];
        hand(f, f, RING_OVER, THUMB_AT_HOME)
    };
}

/// bimanual_hanoi's straddling pinch: index and ring fingers bent down (their base joints
/// at `j0` and `-j0`: positive spreads them apart, negative closes them on each other),
/// the middle finger tucked away, the thumb tucked under the palm (clear of the post and
/// of the other hand).
pub(crate) const fn hanoi_hand(j0: f64) -> Hand {
    hand(
        [j0, 0.8, 0.8, 0.2],
        TUCKED,
        [-j0, 0.8, 0.8, 0.2],
        [THUMB_HOME, 1.1, 1.6, 1.7],
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_hand_lays_its_fingers_out_index_middle_ring_thumb() {
        let h = hand(
            [1.0, 2.0, 3.0, 4.0],
            [5.0; 4],
            [6.0; 4],
            [7.0, 8.0, 9.0, 10.0],
        );
        assert_eq!(&h[..4], &[1.0, 2.0, 3.0, 4.0]);
        assert_eq!(&h[4..12], &[5.0, 5.0, 5.0, 5.0, 6.0, 6.0, 6.0, 6.0]);
        assert_eq!(&h[12..], &[7.0, 8.0, 9.0, 10.0]);
        assert_eq!(FLAT_HAND[12], 0.263);
    }
}
