"""What the stored rows predict: each setting's error and cost past its run, the verdict per
target and horizon, and what a checked prediction must meet."""
