"""Dynamic filter (pipeline step 3): multibody ZMP of the planned whole-body motion and the CoM
correction that cancels its deviation from the walking pattern generator's reference."""
