//! Frequency identification (paper 003). Work in progress.
