"""Learned controllers and the model folders that hold them: the policy behind the one controller
interface (policy.py), a folder's manifest (manifest.py), its weights in a format that cannot run code
(folder.py) and the conversion of an SB3 zip into it (convert.py). The committed folders themselves are
data, under agents/models/."""
