// The race's "teaching" peer: ContinuumRobotExamples' RK4 shooting with its
// Levenberg-Marquardt (ode4, solveLevenbergMarquardt, as published; its
// Library folder on the include path) on a cantilever with a tip force.
// Prints, for each number of points N (N - 1 elements), the median time of
// a solve [us] and the node positions. Built and run by tools/peer_race.py.
#include <iostream>
#include <chrono>
#include <vector>
#include <algorithm>
#include <commonmath.h>
#include <numericalintegration.h>
#include <convexoptimization.h>
using namespace ContinuumRobotLibrary;

static double ALPHA = 3.0;
const double L = 1.0;
// A stiff extension and shear (1e10 N against EI = 1 N m^2): the
// inextensible, unshearable rod softspine models.
const double SHEAR_COMPLIANCE = 1e-10;

// The state the peer's ode4 carries: position (3), rotation matrix column by
// column (9), internal force (3) and moment (3), world frame; no distributed
// load, so the force is constant; bending and torsion stiffness 1.
VectorXd ode(VectorXd state){
    const Matrix3d rotation = Map<Matrix3d>(state.data() + 3);
    const Vector3d force = state.segment<3>(12), moment = state.segment<3>(15);
    const Vector3d strain = SHEAR_COMPLIANCE * rotation.transpose() * force + Vector3d::UnitZ();
    const Vector3d curvature = rotation.transpose() * moment;
    const Vector3d tangent = rotation * strain;
    const Matrix3d turning = rotation * hat(curvature);
    VectorXd rate = VectorXd::Zero(18);
    rate.segment<3>(0) = tangent;
    rate.segment<9>(3) = Map<const VectorXd>(turning.data(), 9);
    rate.segment<3>(15) = force.cross(tangent);
    return rate;
}

template<int N>
struct Shoot {
    static MatrixXd Y;
    static VectorXd f(VectorXd guess){
        VectorXd y0(18);
        y0 << Vector3d::Zero(), Map<VectorXd>(Matrix3d(Matrix3d::Identity()).data(), 9), guess;
        Y = ode4<ode, N>(y0, L);
        Vector3d nL = Y.block<3,1>(12, Y.cols()-1);
        Vector3d mL = Y.block<3,1>(15, Y.cols()-1);
        Vector6d e;
        e << nL - Vector3d(0, -ALPHA, 0), mL;
        return e;
    }
};
template<int N> MatrixXd Shoot<N>::Y;

template<int N>
void run(double tol){
    VectorXd sol;
    std::vector<double> times;
    for(int k = 0; k < 400; k++){
        auto t0 = std::chrono::steady_clock::now();
        try { sol = solveLevenbergMarquardt<Shoot<N>::f>(VectorXd::Zero(6), tol); }
        catch (...) { std::cout << N << " nan\n"; return; }
        auto t1 = std::chrono::steady_clock::now();
        times.push_back(std::chrono::duration<double, std::micro>(t1 - t0).count());
    }
    std::sort(times.begin(), times.end());
    Shoot<N>::f(sol);
    std::cout << N << " " << times[times.size()/2];
    for(int j = 0; j < Shoot<N>::Y.cols(); j++)
        std::cout << " " << Shoot<N>::Y(0,j) << " " << Shoot<N>::Y(1,j) << " " << Shoot<N>::Y(2,j);
    std::cout << "\n";
}

int main(int argc, char** argv){
    ALPHA = atof(argv[1]);
    double tol = argc > 2 ? atof(argv[2]) : 1e-12;
    std::cout.precision(17);
    run<5>(tol); run<6>(tol); run<9>(tol); run<11>(tol); run<17>(tol); run<21>(tol); run<33>(tol); run<41>(tol); run<65>(tol); run<81>(tol); run<129>(tol);
}
