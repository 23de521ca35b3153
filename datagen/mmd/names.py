"""English canonical names for MMD's Japanese bone names, through mmd-bone-tools' dictionary
of MMD's standard and semi-standard bones (e.g. 左ひざ -> ``knee_L``, 上半身2 -> ``upper body2``)
and its word dictionary for hair, skirt and accessory bones (前髪1 -> ``bangs1``)."""
from __future__ import annotations


def english_name(name: str, file_english: str = "") -> tuple[str, str]:
    """(English canonical name, how it was found): ``standard`` (MMD's standard bone table),
    ``words`` (translated word by word), ``file`` (the file's own English name, used when the
    translation still holds Japanese), ``unchanged`` (already ASCII). Without mmd-bone-tools (the
    ``mmd`` extra) the file's English name or the name itself, marked ``no-dictionary``."""
    try:
        from mmd_bone_tools.translate import translate_bone
    except ImportError:
        return (file_english or name), "no-dictionary"
    t = translate_bone(name, "en", fit=False)
    if not t.complete and file_english and file_english.isascii():
        return file_english, "file"
    return t.result, t.method
