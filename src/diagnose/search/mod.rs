//! The loop: the engine that fits the declared model and adds effects one after another ([`engine`]), one
//! round of it ([`round`]: test the residual, fit the candidates it points to, judge, choose), the decision
//! rule ([`decision`]) and what a diagnosis finds ([`diagnosis`]); the verdict on play ([`presence`], checked at
//! other splits by [`stability`], with what a record that is no play looks like instead: [`fold`]).

mod alternatives;
pub mod decision;
pub mod diagnosis;
pub mod engine;
pub mod fold;
pub mod presence;
pub mod round;
pub mod stability;
