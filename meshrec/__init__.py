"""meshrec: recognise a touched object from three probe curves against a folder of meshes."""

__version__ = "0.1.0"
