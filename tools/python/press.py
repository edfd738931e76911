"""The press motion the example clients send (`bridge.py` over iceoryx2, `zenoh_client.py` over Zenoh)."""


def press_height(t, top):
    """Tip height of a press: hover 3 cm above `top`, down 6 mm into it, hold, back up."""
    def smooth(x):
        x = min(max(x, 0.0), 1.0)
        return x * x * (3 - 2 * x)

    above, depth = top + 0.03, top - 0.006
    if t < 0.3:
        return above
    if t < 1.3:
        return above + (depth - above) * smooth(t - 0.3)
    if t < 1.8:
        return depth
    return depth + (above - depth) * smooth((t - 1.8) / 0.8)
