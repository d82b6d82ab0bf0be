//! [`ForwardLog`]: what a forward pass keeps for the backward pass, as an
//! [`Observer`] of it.

use super::kept::KeptCloses;
use super::node::Nodes;
use super::thinned::NodeStates;
use crate::ekf::{Ekf, ProcessNoise, Transition};
use crate::pass::{Epoch, Observer, Updated};

/// The nodes of a forward pass ([`Nodes`]); where the backward pass re-integrates the
/// solution between them (an output step), the solution at each ([`NodeStates`]);
/// where it reads the closes of the covariance step instead of rebuilding them,
/// those ([`KeptCloses`]); where `priors`, the covariance before each node's updates.
#[derive(Clone, Debug, Default)]
pub struct ForwardLog {
    pub nodes: Nodes,
    pub states: Option<NodeStates>,
    pub closes: Option<KeptCloses>,
    pub priors: bool,
}

impl ForwardLog {
    /// The solution at each node, where it is kept.
    fn sync(&mut self, ekf: &Ekf) {
        if let Some(states) = self.states.as_mut() {
            states.sync(&self.nodes, ekf);
        }
    }

    /// At the end of the pass, after the last epoch `epoch`: the node the backward
    /// pass starts from ([`Nodes::finish`]).
    pub fn finish(&mut self, epoch: usize, ekf: &Ekf) {
        self.nodes.finish(epoch, ekf, self.priors);
        self.sync(ekf);
    }
}

impl Observer for ForwardLog {
    fn before_step(&mut self, at: &Epoch<'_>, ekf: &Ekf, noise: ProcessNoise<'_>) {
        self.nodes
            .before_step(at.index - 1, ekf, noise, self.priors);
        self.sync(ekf);
    }

    fn on_close(&mut self, epoch: usize, ekf: &Ekf, phi: &Transition) {
        if let Some(closes) = self.closes.as_mut() {
            closes.note(epoch, ekf, phi);
        }
    }

    fn wants_prior(&self) -> bool {
        self.priors
    }

    fn after_epoch(
        &mut self,
        at: &Epoch<'_>,
        ekf: &Ekf,
        updated: Option<&mut Updated>,
        noise: ProcessNoise<'_>,
    ) {
        if let Some(updated) = updated {
            let prior = updated.prior.take();
            self.nodes
                .after_updates(at.index, ekf, updated.fed, noise, prior);
            self.sync(ekf);
        }
    }
}
