//! The learned noise regressors' predictions, from weights trained in Python: a window of
//! raw IMU samples of one channel in, its per-sample noise variance q out. Training
//! stays in Python (torch, scikit-learn); these are the forward passes the hybrid loop
//! calls hundreds of times per mission.
//!
//! - [`convnet`]: the ProNet CNNs (`BaselineNet`, `DetrendNet`);
//! - [`hcf`]: the handcrafted-feature ensemble (gradient boosting and a random forest).

pub mod convnet;
pub mod hcf;
