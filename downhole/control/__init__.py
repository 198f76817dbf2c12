"""Controllers and optimizers: PI top drive, dynamic programming, EID + LMI, DHP (SNAC)."""
