"""The thesis scene with its trace pictures, and the demo report that runs everything."""
