//! (model in progress)
