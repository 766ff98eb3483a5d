//! Export: writing meshes as OBJ, glTF/GLB and PLY. (Being written.)

mod gltf;
mod obj;
mod ply;
