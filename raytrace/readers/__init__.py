"""Readers of scene and model files: TOML/JSON scenes, OBJ with MTL, glTF/GLB, PLY and other
meshes, image textures. Each gives the scene's own records, or plain arrays, with one-line
errors that name the file and the key."""
