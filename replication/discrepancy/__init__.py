"""Model discrepancy: where the cloth model and the data disagree, which missing
effect explains it, and how much the gap shrinks once it is added."""
