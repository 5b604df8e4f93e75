"""Downstream truth: does a network trained on synthetic RAW work on the real camera?

The paper's own test (Graphics2RAW, Seo et al. ICCV 2023, Tables 1, 2 and S1-S6): train a task
network on synthetic RAW made from CG images, test it on real RAW images of the target camera
with measured truth, beside the same network trained on UPI's synthetic RAW (Brooks et al.
CVPR 2019) and on the real images themselves, and controls that split the gap into the profile's
share and the CG content's.
"""
