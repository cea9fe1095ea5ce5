"""Local geometry at the contact, estimated from the touch curves alone."""
