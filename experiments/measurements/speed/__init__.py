"""Speed: wall time and throughput, each against a reference measured in the same run."""
