"""Registration of touch data onto one model, as a sequence of named stages."""
