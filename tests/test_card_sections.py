"""CARD.md's generated sections: replaced in place between their markers, appended otherwise."""
from mimicbench.datagen.zoo.card import put_card_section

A = "<!-- a -->\nfirst\n<!-- /a -->\n"
A2 = "<!-- a -->\nsecond\n<!-- /a -->\n"
B = "<!-- b -->\nother\n<!-- /b -->\n"


def test_a_missing_card_is_created_with_the_section(tmp_path):
    card = tmp_path / "CARD.md"
    put_card_section(card, "<!-- a -->", "<!-- /a -->", A)
    assert card.read_text() == A


def test_sections_are_appended_then_replaced_in_place(tmp_path):
    card = tmp_path / "CARD.md"
    card.write_text("# Zoo\n\ntext\n")
    put_card_section(card, "<!-- a -->", "<!-- /a -->", A)
    put_card_section(card, "<!-- b -->", "<!-- /b -->", B)
    assert card.read_text() == "# Zoo\n\ntext\n\n" + A + "\n" + B
    put_card_section(card, "<!-- a -->", "<!-- /a -->", A2)  # rewritten where it stood, the rest kept
    assert card.read_text() == "# Zoo\n\ntext\n\n" + A2 + "\n" + B
    put_card_section(card, "<!-- a -->", "<!-- /a -->", A2)  # again: nothing grows
    assert card.read_text() == "# Zoo\n\ntext\n\n" + A2 + "\n" + B
