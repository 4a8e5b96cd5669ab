"""What a frame answered NOT_FOUND says the server lacks: its mesh, or the skeleton or a clip
of its pose. The server names the field and quotes the id ("pose.skeleton_id 'S' ...",
"pose.layers[0].clip_id 'C' ..."); any other NOT_FOUND is the mesh's. The C++ client
library reads it the same way (client/src/lost_upload.cpp)."""
from dataclasses import dataclass
from typing import Optional


@dataclass(frozen=True)
class Lost:
    """kind: "mesh", "skeleton" or "clip"; id: its id on the server."""
    kind: str
    id: str


def _quoted_after(message: str, field: str) -> Optional[str]:
    """The id quoted right after `field` in `message` ("field 'id' ..."), if it is there."""
    at = message.find(field)
    if at < 0:
        return None
    start = at + len(field)
    if message[start:start + 2] != " '":
        return None
    end = message.find("'", start + 2)
    return message[start + 2:end] if end >= 0 else None


def lost_upload(message: str, mesh_id: str) -> Lost:
    """What the NOT_FOUND `message` of a frame of `mesh_id` names as lost."""
    skeleton = _quoted_after(message, "pose.skeleton_id")
    if skeleton is not None:
        return Lost("skeleton", skeleton)
    if "pose.layers[" in message:  # "pose.layers[i].clip_id 'C'": the index is in between
        clip = _quoted_after(message, "].clip_id")
        if clip is not None:
            return Lost("clip", clip)
    return Lost("mesh", mesh_id)
