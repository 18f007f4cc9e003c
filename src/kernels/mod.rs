//! Numerical building blocks the method's stages are made of, with no
//! knowledge of the method: box sums and integral images, separable
//! filters and downscaling, order statistics, powers with run-time CPU
//! dispatch, deterministic parallel reductions and thread pools, and what
//! memory the machine can give.

stage_modules! { boxsum, fastmath, filters, memory, rank, util }
