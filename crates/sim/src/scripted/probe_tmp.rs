//! Temporary probe.
use super::kin::*;
use super::{Recorder, geom_of_body, FLAT_HAND};
use crate::env::TaskEnv;
use crate::error::SimError;

pub(crate) fn probe(env: TaskEnv, hands: &[[f64; 16]]) -> Result<(), SimError> {
    let s = env.state();
    let q = [s[3], s[4], s[5], s[6]];
    let mut rec = Recorder::new(env);
    let p0 = rec.target(0).0;
    rec.go(0, add(p0, [0.0, 0.0, 0.1]), q, FLAT_HAND, 30)?;
    for h in hands {
        rec.go(0, add(p0, [0.0, 0.0, 0.1]), q, *h, 40)?;
        rec.wait(40)?;
        let e = &rec.env;
        let (tp, tq) = tcp(e, 0);
        eprintln!("hand {:?}\n tcp {:.3?} q {:.4?}", h, tp, tq);
        for b in ["ff_tip", "mf_tip", "rf_tip", "th_tip", "allegro_palm"] {
            if let Some(g) = geom_of_body(e, b) {
                let w = e.data().geom_xpos()[g];
                eprintln!("  {b}: world-tcp {:.3?} local {:.3?}", sub(w, tp), mulvt(&qmat(tq), sub(w, tp)));
            }
        }
    }
    Ok(())
}
