# Record the team (the Python program), then ask robot 2's recording why in the past.
python3 examples/tutorial/06_recording_why_in_the_past/main.py "$OUT"
ayllu replay "$OUT/n2.mcap" --at 2s why W.Out    # blocked: robot 1's claim
ayllu replay "$OUT/n2.mcap" --at 7s why W.Out    # open: robot 1's claims lapsed
ayllu replay "$OUT/n2.mcap" check                # the whole recording, bit for bit
