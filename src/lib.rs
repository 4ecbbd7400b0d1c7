//! rkwave
pub mod basis;
pub mod io;
pub mod plot;
pub mod sampling;
