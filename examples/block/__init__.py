"""The paper's block with an ellipsoidal inclusion: its data generator :mod:`examples.block.synthetic`."""
