"""Studies: the paper's numerical study (and, later, the penalty study)."""
