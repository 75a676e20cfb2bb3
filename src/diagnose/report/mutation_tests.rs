//! Tests that pin behaviour a mutation sample found unchecked.

use super::*;

/// The figures' curves pair each x with its y, in order, one point per sample (a curve of one point would
/// draw nothing the reader can check).
#[test]
fn points_pair_every_sample_in_order() {
    let got = pts(&[0.5, 1.5, 2.5], &[-1.0, 4.0, 9.0]);
    assert_eq!(got, vec![(0.5, -1.0), (1.5, 4.0), (2.5, 9.0)]);
}
