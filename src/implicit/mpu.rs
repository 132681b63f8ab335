//! Multi-level partition of unity implicits (Ohtake et al. 2003). Being written.
