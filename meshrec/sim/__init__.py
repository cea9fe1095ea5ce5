"""The simulator: touches sampled from models, and the paper's analytic surfaces."""
