//! # Plants
//!
//! Plant definitions and their simulation. This branch holds only the ODE plants ([`ode`]);
//! the plant specs and the simulator live beside them on main.
//!
//! ## References
//! - See [`ode`].

pub mod ode;
