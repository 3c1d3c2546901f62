//! flame
