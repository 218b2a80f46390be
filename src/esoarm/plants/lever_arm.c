/* Plant kind "lever-arm" on the chip: the observer's input is the command itself
 * (esoarm.plants.lever_arm.observer_input). */
static esoarm_real plant_observer_input(const esoarm_real zhat[], esoarm_real u)
{
    (void)zhat;
    return u;
}
