//! MRGIA (paper 000). Work in progress.
